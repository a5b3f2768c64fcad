#!/usr/bin/env python3
"""Helpers of eval_hard_cases.sh (needs Debian's python3 with rosbag and numpy).

  hard_case_metrics.py gt BAG GT.txt
      Writes the bag's nav_msgs/Odometry ground truth (topic ground_truth) as KITTI 3x4 rows relative to
      the first pose and prints `frames N period_s P` (P: median spacing of the message stamps).
  hard_case_metrics.py compare GT.txt EST.txt
      Both relative to their first pose, no alignment. Prints
      `max_heading_deg H backward_steps B of S min_step_cos C step_rot_p90_deg R step_rot_max_deg M`: the
      largest yaw difference; how many estimated steps point against the true step (dot product < 0) among
      the S true steps longer than MIN_STEP_M (C: the smallest cosine between estimated and true step among
      them); and the 90th percentile and largest rotation error of a single step (sweep to sweep), which
      short-lived heading errors (a yaw burst's first sweeps) dominate while the drift over segments
      averages them with the steady stretches.
"""
import math
import os
import sys

import numpy as np

# The pose helpers of the demo report (scripts/aloam_poses.py).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts"))
from aloam_poses import quat_to_rot, read_kitti, write_kitti  # noqa: E402

MIN_STEP_M = 0.05


def pose_to_matrix(pose):
    q = pose.orientation
    m = np.eye(4)
    m[:3, :3] = quat_to_rot(q.x, q.y, q.z, q.w)
    m[:3, 3] = [pose.position.x, pose.position.y, pose.position.z]
    return m


def ground_truth(bag_path, out_path):
    import rosbag
    poses, stamps = [], []
    with rosbag.Bag(bag_path) as bag:
        for _, msg, _ in bag.read_messages(topics=["ground_truth"]):
            poses.append(pose_to_matrix(msg.pose.pose))
            stamps.append(msg.header.stamp.to_sec())
    if not poses:
        sys.exit("no ground_truth messages in " + bag_path)
    first_inv = np.linalg.inv(poses[0])
    write_kitti(out_path, [first_inv @ m for m in poses])
    period = float(np.median(np.diff(stamps))) if len(stamps) > 1 else float("nan")
    print("frames %d period_s %.3f" % (len(poses), period))


def yaw(m):
    return math.atan2(m[1, 0], m[0, 0])


def compare(gt_path, est_path):
    gt, est = read_kitti(gt_path), read_kitti(est_path)
    n = min(len(gt), len(est))
    if n < 2:
        sys.exit("fewer than two common poses")
    gt0, est0 = np.linalg.inv(gt[0]), np.linalg.inv(est[0])
    gt = [gt0 @ m for m in gt[:n]]
    est = [est0 @ m for m in est[:n]]
    heading = max(abs(math.degrees(math.remainder(yaw(e) - yaw(g), 2.0 * math.pi))) for e, g in zip(est, gt))
    backward, steps, min_cos = 0, 0, 1.0
    step_rot = []
    for i in range(n - 1):
        error = np.linalg.inv(gt[i + 1]) @ gt[i] @ np.linalg.inv(est[i]) @ est[i + 1]
        step_rot.append(rotation_deg(error))
        true_step = gt[i + 1][:3, 3] - gt[i][:3, 3]
        est_step = est[i + 1][:3, 3] - est[i][:3, 3]
        length = np.linalg.norm(true_step)
        if length <= MIN_STEP_M:
            continue
        steps += 1
        dot = float(np.dot(true_step, est_step))
        if dot < 0.0:
            backward += 1
        est_length = np.linalg.norm(est_step)
        min_cos = min(min_cos, dot / (length * est_length) if est_length > 0.0 else 0.0)
    print("max_heading_deg %.2f backward_steps %d of %d min_step_cos %.2f step_rot_p90_deg %.2f step_rot_max_deg %.2f" %
          (heading, backward, steps, min_cos, np.percentile(step_rot, 90), max(step_rot)))


def rotation_deg(m):
    return math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(m[:3, :3]) - 1.0) / 2.0))))


def main():
    if len(sys.argv) == 4 and sys.argv[1] == "gt":
        ground_truth(sys.argv[2], sys.argv[3])
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        compare(sys.argv[2], sys.argv[3])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()

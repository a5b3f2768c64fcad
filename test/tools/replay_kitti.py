#!/usr/bin/env python3
"""Replays a KITTI-layout sequence into a running aloam_nodelet pipeline, frame by frame.

Publishes each velodyne/*.bin as sensor_msgs/PointCloud2 (x y z intensity, float32) on velodyne_points,
waits for the answer on aft_mapped_to_init with that frame's stamp, and writes the answered poses as
KITTI rows (relative to the first answer) for aloam_eval. Exits non-zero when a frame goes unanswered.

Usage: replay_kitti.py DIR OUT.txt [--timeout S] [--max-frames N]
                       [--at-frame K --then "COMMAND"]   (runs COMMAND once before frame K)
"""
import argparse
import glob
import math
import os
import subprocess
import sys
import threading

import numpy as np
import rospy
from nav_msgs.msg import Odometry
from sensor_msgs.msg import PointCloud2, PointField

FIELDS = [PointField(name, 4 * i, PointField.FLOAT32, 1) for i, name in enumerate("x y z intensity".split())]
# KITTI's elevation correction, as aloam_offline applies it (see io/kitti_dataset.h).
VERTICAL_CORRECTION_DEG = 0.205


def corrected(points):
    """Raises every point's elevation by the KITTI correction, keeping its range."""
    xyz = points[:, :3].astype(np.float64)
    horizontal = np.hypot(xyz[:, 0], xyz[:, 1])
    elevation = np.arctan2(xyz[:, 2], horizontal) + math.radians(VERTICAL_CORRECTION_DEG)
    rng = np.linalg.norm(xyz, axis=1)
    scale = np.where(horizontal > 1e-9, rng * np.cos(elevation) / np.maximum(horizontal, 1e-9), 1.0)
    out = points.copy()
    out[:, 0] = xyz[:, 0] * scale
    out[:, 1] = xyz[:, 1] * scale
    out[:, 2] = np.where(horizontal > 1e-9, rng * np.sin(elevation), xyz[:, 2])
    return out


def cloud_message(points, stamp):
    msg = PointCloud2()
    msg.header.stamp = stamp
    msg.header.frame_id = "velodyne"
    msg.height = 1
    msg.width = points.shape[0]
    msg.fields = FIELDS
    msg.is_bigendian = False
    msg.point_step = 16
    msg.row_step = 16 * points.shape[0]
    msg.is_dense = True
    msg.data = points.astype(np.float32).tobytes()
    return msg


def pose_matrix(odom):
    p, q = odom.pose.pose.position, odom.pose.pose.orientation
    x, y, z, w = q.x, q.y, q.z, q.w
    rot = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = [p.x, p.y, p.z]
    return m


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("sequence")
    parser.add_argument("output")
    parser.add_argument("--timeout", type=float, default=10.0)
    parser.add_argument("--max-frames", type=int, default=0)
    parser.add_argument("--at-frame", type=int, default=-1)
    parser.add_argument("--then", default="")
    args = parser.parse_args(rospy.myargv()[1:])

    files = sorted(glob.glob(os.path.join(args.sequence, "velodyne", "*.bin")))
    if args.max_frames > 0:
        files = files[:args.max_frames]
    rospy.init_node("replay_kitti", anonymous=True)
    answers = {}
    answered = threading.Condition()

    def on_pose(msg):
        with answered:
            answers[msg.header.stamp.to_nsec()] = msg
            answered.notify_all()

    rospy.Subscriber("aft_mapped_to_init", Odometry, on_pose, queue_size=100)
    pub = rospy.Publisher("velodyne_points", PointCloud2, queue_size=1)
    deadline = rospy.Time.now() + rospy.Duration(args.timeout)
    while pub.get_num_connections() == 0 and rospy.Time.now() < deadline and not rospy.is_shutdown():
        rospy.sleep(0.05)

    poses, missing = [], 0
    base = rospy.Time(1000.0)
    for i, path in enumerate(files):
        if i == args.at_frame and args.then:
            print("frame %d: running %s" % (i, args.then), flush=True)
            subprocess.run(args.then, shell=True, check=True)
        points = corrected(np.fromfile(path, dtype=np.float32).reshape(-1, 4))
        stamp = base + rospy.Duration(0.1 * i)
        pub.publish(cloud_message(points, stamp))
        with answered:
            ok = answered.wait_for(lambda: stamp.to_nsec() in answers or rospy.is_shutdown(), args.timeout)
        if not ok or stamp.to_nsec() not in answers:
            missing += 1
            print("frame %d: no answer within %.1f s" % (i, args.timeout), flush=True)
            poses.append(poses[-1] if poses else np.eye(4))
            continue
        poses.append(pose_matrix(answers[stamp.to_nsec()]))
        if i % 10 == 0:
            print("frame %d/%d answered" % (i + 1, len(files)), flush=True)

    first_inv = np.linalg.inv(poses[0])
    with open(args.output, "w") as out:
        for m in poses:
            rel = first_inv @ m
            out.write(" ".join("%.9e" % v for v in rel[:3, :].reshape(-1)) + "\n")
    print("%d frames, %d answered, %d unanswered; poses in %s" % (len(files), len(files) - missing, missing,
                                                                     args.output))
    sys.exit(1 if missing else 0)


if __name__ == "__main__":
    main()

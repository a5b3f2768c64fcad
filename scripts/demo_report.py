#!/usr/bin/env python3
"""Evaluates and plots a mapped trajectory for scripts/demo.sh.

Pairs the estimate with the ground truth frame by frame, writes both as KITTI rows relative to the first
pair, runs aloam_eval on them, draws a PNG (top view of estimate over ground truth; translation error over
distance travelled) and writes summary.txt.

  demo_report.py --out DIR --estimate-tum EST.tum --bag SIM.bag [--eval BIN] [--segments LIST]
      estimate from /laser_mapping/save_trajectory (TUM, stamped: frames mapping skipped are absent),
      ground truth from the simulated bag (ground_truth, one per velodyne_points sweep)
  demo_report.py --out DIR --estimate-kitti EST.txt [--gt POSES.txt [--calib calib.txt]] [--start N] ...
      estimate of a KITTI-layout sequence, one row per frame; ground truth in camera-0 coordinates when
      --calib is given (KITTI's poses), else lidar poses. Without --gt: plot and summary of the estimate.
"""
import argparse
import os
import re
import subprocess
import sys

import numpy as np

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt  # noqa: E402 (after the backend choice)

from aloam_poses import quat_to_rot, read_kitti, write_kitti  # noqa: E402 (beside this script)


def read_tum(path):
    """{stamp in microseconds: 4x4 pose} of a TUM file (stamp tx ty tz qx qy qz qw)."""
    poses = {}
    with open(path) as f:
        for line in f:
            values = line.split()
            if len(values) != 8 or line.startswith("#"):
                continue
            v = [float(x) for x in values]
            m = np.eye(4)
            m[:3, :3] = quat_to_rot(*v[4:8])
            m[:3, 3] = v[1:4]
            poses[int(round(v[0] * 1e6))] = m
    return poses


def bag_truth(path):
    """{sweep header stamp in microseconds: ground-truth pose at the sweep end}. aloam_sim records one
    ground_truth message per sweep, in the same order as the clouds."""
    import rosbag
    clouds, truth = [], []
    with rosbag.Bag(path) as bag:
        for topic, msg, _ in bag.read_messages(topics=["velodyne_points", "ground_truth"]):
            if topic == "velodyne_points":
                clouds.append(int(round(msg.header.stamp.to_sec() * 1e6)))
            else:
                p, q = msg.pose.pose.position, msg.pose.pose.orientation
                m = np.eye(4)
                m[:3, :3] = quat_to_rot(q.x, q.y, q.z, q.w)
                m[:3, 3] = [p.x, p.y, p.z]
                truth.append(m)
    if len(clouds) != len(truth):
        raise SystemExit("demo_report: %s holds %d sweeps but %d ground-truth poses" % (path, len(clouds), len(truth)))
    return dict(zip(clouds, truth))


def calib_tr(path):
    """Velodyne -> camera 0 (4x4) from the Tr: line of a KITTI calib.txt."""
    with open(path) as f:
        for line in f:
            if line.startswith("Tr:"):
                m = np.eye(4)
                m[:3, :] = np.array([float(v) for v in line.split()[1:13]]).reshape(3, 4)
                return m
    raise SystemExit("demo_report: no Tr: line in %s" % path)


def relative(poses):
    first_inv = np.linalg.inv(poses[0])
    return np.array([first_inv @ m for m in poses])


def run_eval(binary, gt, est, start, segments):
    cmd = [binary, "--gt", gt, "--trajectory", est, "--start", str(start), "--segments", segments]
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
    metrics = {}
    for line in proc.stdout.splitlines():
        m = re.match(r"^\s*([a-z_%/0-9]+)\s*:\s*([-+0-9.eE]+|nan|inf)\s*$", line)
        if m:
            metrics[m.group(1)] = float(m.group(2))
    return metrics, proc.stdout, proc.returncode


def plot(path, title, est, gt, start):
    """Top view and translation error over distance (both trajectories relative to their first pose)."""
    fig, (top, err) = plt.subplots(1, 2, figsize=(13, 5.5), gridspec_kw={"width_ratios": [1.2, 1]})
    if gt is not None:
        top.plot(gt[:, 0, 3], gt[:, 1, 3], color="0.2", lw=3.0, alpha=0.45, label="ground truth")
    top.plot(est[:, 0, 3], est[:, 1, 3], color="tab:red", lw=1.3, label="aloam_nodelet (mapped)")
    top.plot(est[0, 0, 3], est[0, 1, 3], "o", color="tab:green", label="start")
    top.set_xlabel("x (m, lidar frame of the first sweep)")
    top.set_ylabel("y (m)")
    top.set_aspect("equal", adjustable="datalim")
    top.grid(True, alpha=0.3)
    top.legend(loc="best")
    top.set_title("top view")
    if gt is not None:
        steps = np.linalg.norm(np.diff(gt[:, :3, 3], axis=0), axis=1)
        distance = np.concatenate([[0.0], np.cumsum(steps)])
        error = np.linalg.norm(est[:, :3, 3] - gt[:, :3, 3], axis=1)
        err.plot(distance, error, color="tab:red")
        if start > 0:
            err.axvline(distance[min(start, len(distance) - 1)], color="0.5", ls="--", lw=1,
                        label="evaluation starts (frame %d)" % start)
            err.legend(loc="upper left")
        err.set_xlabel("distance travelled (m)")
        err.set_ylabel("translation error (m)")
        err.set_title("error against ground truth (no alignment)")
        err.grid(True, alpha=0.3)
    else:
        err.axis("off")
        err.text(0.5, 0.5, "no ground truth in the input", ha="center", va="center")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True)
    parser.add_argument("--estimate-tum")
    parser.add_argument("--bag")
    parser.add_argument("--estimate-kitti")
    parser.add_argument("--gt")
    parser.add_argument("--calib")
    parser.add_argument("--start", type=int, default=0)
    parser.add_argument("--segments", default="10,20,40")
    parser.add_argument("--eval", default="aloam_eval")
    parser.add_argument("--title", default="aloam_nodelet")
    parser.add_argument("--frames-in", type=int, default=0, help="frames played (for the summary)")
    args = parser.parse_args()

    if args.estimate_tum:
        if not args.bag:
            parser.error("--estimate-tum needs --bag")
        estimate, truth_by_stamp = read_tum(args.estimate_tum), bag_truth(args.bag)
        stamps = sorted(s for s in estimate if s in truth_by_stamp)
        if len(stamps) < 2:
            raise SystemExit("demo_report: fewer than 2 mapped frames match the bag's sweeps")
        est = relative(np.array([estimate[s] for s in stamps]))
        gt = relative(np.array([truth_by_stamp[s] for s in stamps]))
        frames_in = len(truth_by_stamp)
    elif args.estimate_kitti:
        est = relative(read_kitti(args.estimate_kitti))
        gt = None
        if args.gt:
            raw = read_kitti(args.gt)
            if args.calib:  # KITTI camera-0 poses -> lidar poses
                tr = calib_tr(args.calib)
                raw = np.array([np.linalg.inv(tr) @ m @ tr for m in raw])
            n = min(len(raw), len(est))
            est, gt = est[:n], relative(raw[:n])
        frames_in = args.frames_in or len(est)
    else:
        parser.error("give --estimate-tum with --bag, or --estimate-kitti")

    os.makedirs(args.out, exist_ok=True)
    est_path = os.path.join(args.out, "estimate_eval_kitti.txt")
    write_kitti(est_path, est)
    lines = ["aloam_nodelet demo: %s" % args.title,
             "frames: %d in, %d mapped and evaluated" % (frames_in, len(est))]
    metrics = {}
    if gt is not None:
        gt_path = os.path.join(args.out, "ground_truth_eval_kitti.txt")
        write_kitti(gt_path, gt)
        metrics, report, status = run_eval(args.eval, gt_path, est_path, args.start, args.segments)
        if status != 0:
            print(report, file=sys.stderr)
            raise SystemExit("demo_report: aloam_eval failed")
        steps = np.linalg.norm(np.diff(gt[:, :3, 3], axis=0), axis=1)
        final = np.linalg.norm(est[-1, :3, 3] - gt[-1, :3, 3])
        lines += ["path length: %.1f m (ground truth)" % steps.sum(),
                  "translation drift: %.3f %% (segments %s m, from frame %d)"
                  % (metrics.get("translation_drift_percent", float("nan")), args.segments, args.start),
                  "rotation drift: %.3f deg/100 m" % metrics.get("rotation_deg_per_100m", float("nan")),
                  "ATE (aligned, RMSE): %.3f m, max %.3f m" % (metrics.get("ate_rmse_m", float("nan")),
                                                            metrics.get("ate_max_m", float("nan"))),
                  "end-point error (unaligned): %.3f m" % final,
                  "", "aloam_eval:", report.rstrip()]
    else:
        lines += ["path length: %.1f m (estimate)" % np.linalg.norm(np.diff(est[:, :3, 3], axis=0), axis=1).sum(),
                  "no ground truth: not evaluated"]
    png = os.path.join(args.out, "trajectory.png")
    plot(png, args.title, est, gt, args.start)
    with open(os.path.join(args.out, "summary.txt"), "a") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines[:8]))


if __name__ == "__main__":
    main()

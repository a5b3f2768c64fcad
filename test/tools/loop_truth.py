#!/usr/bin/env python3
"""Checks the loops aloam_offline --loop-closure accepted against the simulator's ground truth.

  loop_truth.py LOOPS.tsv GT.txt EST.txt [MAX_M MAX_DEG]
      LOOPS.tsv: aloam_offline --loops; GT.txt: hard_case_metrics.py gt (KITTI rows, one per sweep, relative
      to the first); EST.txt: the loop-corrected trajectory (same rows). A loop is false when its relative
      pose differs from the true one between the two sweeps by more than MAX_M metres (default 0.5) or
      MAX_DEG degrees (default 2). Prints
      `tried T accepted A false F worst_m W worst_deg D end_error_m E` (E: the last pose against the truth,
      both relative to their first pose) and one line per false loop.
"""
import csv
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts"))
from aloam_poses import quat_to_rot, read_kitti  # noqa: E402


def main():
    if len(sys.argv) not in (4, 6):
        sys.exit(__doc__)
    loops_path, gt_path, est_path = sys.argv[1:4]
    max_m = float(sys.argv[4]) if len(sys.argv) == 6 else 0.5
    max_deg = float(sys.argv[5]) if len(sys.argv) == 6 else 2.0
    gt = read_kitti(gt_path)
    est = read_kitti(est_path)
    tried = accepted = false = 0
    worst_m = worst_deg = 0.0
    with open(loops_path) as f:
        for row in csv.DictReader(f, delimiter="\t"):
            tried += 1
            if row["accepted"] != "1":
                continue
            accepted += 1
            a, b = int(row["from_frame"]), int(row["to_frame"])
            if a >= len(gt) or b >= len(gt):
                print(f"loop {row['from']} -> {row['to']}: frame {a} or {b} beyond the ground truth")
                false += 1
                continue
            truth = np.linalg.inv(gt[a]) @ gt[b]
            rel = np.eye(4)
            rel[:3, :3] = quat_to_rot(*(float(row[k]) for k in ("rel_qx", "rel_qy", "rel_qz", "rel_qw")))
            rel[:3, 3] = [float(row[k]) for k in ("rel_x", "rel_y", "rel_z")]
            diff = np.linalg.inv(truth) @ rel
            err_m = float(np.linalg.norm(diff[:3, 3]))
            err_deg = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(diff[:3, :3]) - 1.0) / 2.0))))
            worst_m, worst_deg = max(worst_m, err_m), max(worst_deg, err_deg)
            if err_m > max_m or err_deg > max_deg:
                false += 1
                print(f"false loop {row['from']} -> {row['to']} (frames {a} -> {b}, {row['source']}): "
                      f"{err_m:.2f} m, {err_deg:.2f} deg off the truth")
    n = min(len(gt), len(est))
    end = float(np.linalg.norm(est[n - 1][:3, 3] - gt[n - 1][:3, 3])) if n else float("nan")
    print(f"tried {tried} accepted {accepted} false {false} worst_m {worst_m:.3f} worst_deg {worst_deg:.3f} "
          f"end_error_m {end:.3f}")


if __name__ == "__main__":
    main()

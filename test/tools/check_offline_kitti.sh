#!/usr/bin/env bash
# End-to-end check of the installed tools on real data: aloam_offline on KITTI 00 frames 0-100, then
# aloam_eval from frame 6 with 10-70 m segments, against A-LOAM's figures on the same frames. The same
# frames with --loop-closure (they hold no revisit) must give the same trajectory, byte for byte.
# Usage: check_offline_kitti.sh BIN_DIR KITTI_DIR OUT_DIR
# Exit 0: passed; 1: failed; 77: skipped (no data), with the reason printed.
set -euo pipefail
source "$(dirname "$0")/check_lib.sh"
bin="$1" data="$2" out="$3"
max_drift=1.449  # A-LOAM, translation drift %
max_ate=0.167    # A-LOAM, ATE after alignment (m)

if [ ! -d "$data/velodyne" ] || [ ! -f "$data/poses_kitti_gt.txt" ]; then
  echo "SKIPPED offline KITTI check: no KITTI data at $data"
  exit 77
fi
mkdir -p "$out"
"$bin/aloam_offline" --kitti "$data" --sensor HDL64 --trajectory "$out/trajectory.txt" \
  --tum "$out/trajectory.tum" --map "$out/map.pcd" | tee "$out/offline.txt"
"$bin/aloam_eval" --gt "$data/poses_kitti_gt.txt" --calib "$data/calib.txt" \
  --trajectory "$out/trajectory.txt" --start 6 --segments 10,20,30,40,50,60,70 | tee "$out/eval.txt"

"$bin/aloam_offline" --kitti "$data" --sensor HDL64 --trajectory "$out/trajectory_loops.txt" --loop-closure \
  --loops "$out/loops.tsv" | tee "$out/offline_loops.txt"

frames=$(grep -c . "$out/trajectory.txt")
expected=$(find "$data/velodyne" -name '*.bin' | wc -l)
drift=$(figure translation_drift_percent "$out/eval.txt")
ate=$(figure ate_rmse_m "$out/eval.txt")
status=0
[ "$frames" -eq "$expected" ] || { echo "FAIL: $frames poses for $expected scans"; status=1; }
[ -s "$out/map.pcd" ] || { echo "FAIL: no map written"; status=1; }
cmp -s "$out/trajectory.txt" "$out/trajectory_loops.txt" ||
  { echo "FAIL: the trajectory differs with --loop-closure (no frame revisits a place)"; status=1; }
at_most "drift (%)" "$drift" "$max_drift" || status=1
at_most "ATE (m)" "$ate" "$max_ate" || status=1
[ $status -eq 0 ] && echo "PASSED offline KITTI check: drift $drift % (<= $max_drift), ATE $ate m (<= $max_ate), identical with --loop-closure"
exit $status

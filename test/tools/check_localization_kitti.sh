#!/usr/bin/env bash
# Localization in a saved map on real data: map KITTI 00 frames 0-100 with aloam_offline --save-map, then
# localize frames 40-100 in that map from an initial pose 0.5 m / 0.3 m / 5 deg off the mapped one. Every
# frame must be answered, within 0.10 m / 0.5 deg of the mapped poses from the 5th answer on; the map must
# come out unchanged (same points); 20 m off must end lost, never localized; global localization (no
# initial pose) from frames 50, 70 and 90 must find the mapped pose (0.10 m / 0.5 deg from the 3rd answer).
# Usage: check_localization_kitti.sh BIN_DIR KITTI_DIR OUT_DIR
# Exit 0: passed; 1: failed; 77: skipped (no data), with the reason printed.
set -euo pipefail
source "$(dirname "$0")/check_lib.sh"
bin="$1" data="$2" out="$3"
here="$(cd "$(dirname "$0")" && pwd)"
max_error_m=0.10
max_error_deg=0.5

if [ ! -d "$data/velodyne" ]; then
  echo "SKIPPED localization KITTI check: no KITTI data at $data"
  exit 77
fi
mkdir -p "$out"
errors() { /usr/bin/python3 "$here/localization_errors.py" "$@"; }
status=0

"$bin/aloam_offline" --kitti "$data" --sensor HDL64 --trajectory "$out/mapped.txt" --save-map "$out/map.pcd" \
  | tee "$out/mapping.txt"

# From 0.5 m / 0.3 m / 5 deg off.
initial=$(errors initial "$out/mapped.txt" 40 0.5 0.3 0 5)
"$bin/aloam_offline" --kitti "$data" --sensor HDL64 --trajectory "$out/localized.txt" --localize "$out/map.pcd" \
  --initial-pose "$initial" --start-frame 40 --localization-log "$out/localized_log.txt" \
  --map-after "$out/map_after.pcd" | tee "$out/localize.txt"
errors compare "$out/mapped.txt" "$out/localized.txt" 40 "$out/localized_log.txt" 5 | tee "$out/figures.txt"
[ "$(figure frames "$out/figures.txt")" -eq 61 ] || { echo "FAIL: not 61 frames"; status=1; }
[ "$(figure answered "$out/figures.txt")" -eq 61 ] || { echo "FAIL: not every frame answered"; status=1; }
at_most "error from the 5th answer (m)" "$(figure max_translation_error_m "$out/figures.txt")" $max_error_m || status=1
at_most "error from the 5th answer (deg)" "$(figure max_rotation_error_deg "$out/figures.txt")" $max_error_deg || status=1
[ "$(figure final_state "$out/figures.txt")" = localized ] || { echo "FAIL: not localized at the end"; status=1; }
errors same_map "$out/map.pcd" "$out/map_after.pcd" | tee "$out/map_check.txt"
[ "$(figure same_points "$out/map_check.txt")" = yes ] || { echo "FAIL: the map changed"; status=1; }

# 20 m off across the road: lost, never a confident wrong pose.
initial=$(errors initial "$out/mapped.txt" 40 0 20 0 0)
"$bin/aloam_offline" --kitti "$data" --sensor HDL64 --trajectory "$out/wrong.txt" --localize "$out/map.pcd" \
  --initial-pose "$initial" --start-frame 40 --max-frames 20 --localization-log "$out/wrong_log.txt" \
  | tee "$out/wrong_run.txt"
errors compare "$out/mapped.txt" "$out/wrong.txt" 40 "$out/wrong_log.txt" 1 | tee "$out/wrong_figures.txt"
[ "$(figure localized_frames "$out/wrong_figures.txt")" -eq 0 ] || { echo "FAIL: 20 m off localized"; status=1; }
[ "$(figure final_state "$out/wrong_figures.txt")" = lost ] || { echo "FAIL: 20 m off not lost"; status=1; }

# Global localization: no initial pose.
for start in 50 70 90; do
  "$bin/aloam_offline" --kitti "$data" --sensor HDL64 --trajectory "$out/global_$start.txt" --localize "$out/map.pcd" \
    --global --start-frame $start --max-frames 8 --localization-log "$out/global_${start}_log.txt" \
    | tee "$out/global_${start}_run.txt"
  errors compare "$out/mapped.txt" "$out/global_$start.txt" $start "$out/global_${start}_log.txt" 3 \
    | tee "$out/global_${start}_figures.txt"
  echo "global from frame $start: first search $(awk '/first search:/ {print $7}' "$out/global_${start}_run.txt") ms"
  [ "$(figure final_state "$out/global_${start}_figures.txt")" = localized ] || { echo "FAIL: global $start"; status=1; }
  at_most "global from $start (m)" "$(figure max_translation_error_m "$out/global_${start}_figures.txt")" $max_error_m ||
    status=1
  at_most "global from $start (deg)" "$(figure max_rotation_error_deg "$out/global_${start}_figures.txt")" \
    $max_error_deg || status=1
done

[ $status -eq 0 ] && echo "PASSED localization KITTI check: frames 40-100 within" \
  "$(figure max_translation_error_m "$out/figures.txt") m / $(figure max_rotation_error_deg "$out/figures.txt") deg" \
  "from the 5th answer, map unchanged, 20 m off lost, global found from 3 of 3 starts"
exit $status

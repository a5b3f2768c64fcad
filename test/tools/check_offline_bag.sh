#!/usr/bin/env bash
# End-to-end check of aloam_offline --bag: simulated VLP-16 sweeps with motion distortion written to a
# rosbag, mapped with deskewing, evaluated against the simulator's exact ground truth. Needs no data.
# Usage: check_offline_bag.sh BIN_DIR OUT_DIR
set -euo pipefail
source "$(dirname "$0")/check_lib.sh"
bin="$1" out="$2"
max_drift=1.0   # % over 5-20 m segments (measured 0.46)
max_ate=0.06    # m (measured 0.023)
mkdir -p "$out"
"$bin/make_test_bag" "$out/street.bag" "$out/ground_truth.txt" VLP16 40
"$bin/aloam_offline" --bag "$out/street.bag" --topic velodyne_points --sensor VLP16 --deskew \
  --trajectory "$out/trajectory.txt" --tum "$out/trajectory.tum" | tee "$out/offline.txt"
"$bin/aloam_eval" --gt "$out/ground_truth.txt" --trajectory "$out/trajectory.txt" \
  --segments 5,10,20 | tee "$out/eval.txt"
drift=$(figure translation_drift_percent "$out/eval.txt")
ate=$(figure ate_rmse_m "$out/eval.txt")
status=0
[ "$(grep -c . "$out/trajectory.txt")" -eq 40 ] || { echo "FAIL: expected 40 poses"; status=1; }
[ "$(grep -c . "$out/trajectory.tum")" -eq 40 ] || { echo "FAIL: expected 40 TUM poses"; status=1; }
at_most "drift (%)" "$drift" "$max_drift" || status=1
at_most "ATE (m)" "$ate" "$max_ate" || status=1
[ $status -eq 0 ] && echo "PASSED offline bag check: drift $drift % (<= $max_drift), ATE $ate m (<= $max_ate)"
exit $status

#!/usr/bin/env bash
# The urban car drive simulated with every sensor preset (issue 11, item 4: wide vertical FOV and mixed
# beam spacing): for each preset and seed, aloam_sim writes a bag, aloam_offline --deskew maps it and
# aloam_evaluation compares with the simulator's exact ground truth, as eval_hard_cases.sh does.
# Reports only (no bounds).
#
# Usage: eval_sensor_suite.sh BIN_DIR OUT_DIR [ALOAM_OFFLINE_ARGS...]
#   BIN_DIR             devel/lib/aloam_nodelet (aloam_sim, aloam_offline, aloam_eval)
#   OUT_DIR             scratch folder: per run logs, trajectories and the table (results.txt)
#   ALOAM_OFFLINE_ARGS  passed on to every aloam_offline run (e.g. --baseline)
# Environment: SEEDS (default "1 2"), SENSORS (default all presets), DURATION (s, default 8).
# Needs Debian's python3 (rosbag, numpy) first on PATH and the workspace's setup.bash sourced.
#
# Columns: ATE (m, after rigid alignment), translation drift (%) and rotation drift (deg/100 m) over
# 10, 20 and 50 m segments.
set -uo pipefail
if [ $# -lt 2 ]; then
  sed -n '2,16p' "$0" >&2
  exit 2
fi
bin="$1" out="$2"
shift 2
offline_args=("$@")
metrics="$(cd "$(dirname "$0")" && pwd)/hard_case_metrics.py"
seeds="${SEEDS:-1 2}"
sensors="${SENSORS:-VLP16 HDL32 HDL64 VLP32C OS1_64 OS0_64 OS1_128}"
duration="${DURATION:-8}"
mkdir -p "$out"

figure() { awk -v k="$1:" '$1 == k {print $2}' "$2"; }

results="$out/results.txt"
echo "# aloam_offline extra args: ${offline_args[*]:-(none)}" | tee "$results"
printf "%-8s %4s %8s %9s %12s\n" sensor seed ate_m drift_% "rot_deg/100m" | tee -a "$results"
start_all=$(date +%s)
status=0
for sensor in $sensors; do
  for seed in $seeds; do
    run="$out/${sensor}_s$seed"
    mkdir -p "$run"
    bag="$run/sim.bag"
    if ! "$bin/aloam_sim" --sensor "$sensor" --scene urban --trajectory car --duration "$duration" --seed "$seed" \
      --bag "$bag" >"$run/sim.txt" 2>&1 ||
      ! "$bin/aloam_offline" --bag "$bag" --topic velodyne_points --sensor "$sensor" --deskew \
        --trajectory "$run/est.txt" "${offline_args[@]}" >"$run/offline.txt" 2>&1 ||
      ! python3 "$metrics" gt "$bag" "$run/gt.txt" >"$run/gt_info.txt" 2>&1 ||
      ! "$bin/aloam_eval" --gt "$run/gt.txt" --trajectory "$run/est.txt" --segments 10,20,50 \
        >"$run/eval.txt" 2>&1; then
      printf "%-8s %4s FAILED (see %s)\n" "$sensor" "$seed" "$run" | tee -a "$results"
      status=1
      continue
    fi
    rm -f "$bag"
    printf "%-8s %4s %8s %9s %12s\n" "$sensor" "$seed" "$(figure ate_rmse_m "$run/eval.txt")" \
      "$(figure translation_drift_percent "$run/eval.txt")" "$(figure rotation_deg_per_100m "$run/eval.txt")" |
      tee -a "$results"
  done
done
echo "# $(($(date +%s) - start_all)) s; per-run files under $out" | tee -a "$results"
exit $status

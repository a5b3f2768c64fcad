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
# 10, 20 and 50 m segments. A-LOAM's ATE and rotation drift on the same sweeps beside them when A-LOAM is
# built (as in eval_hard_cases.sh; "-" for the presets A-LOAM has no launch values for).
set -uo pipefail
source "$(dirname "$0")/check_lib.sh"
need_args 2 $#
bin="$1" out="$2"
shift 2
offline_args=("$@")
seeds="${SEEDS:-1 2}"
sensors="${SENSORS:-VLP16 HDL32 HDL64 VLP32C OS1_64 OS0_64 OS1_128}"
duration="${DURATION:-8}"
mkdir -p "$out"

results="$out/results.txt"
echo "# aloam_offline extra args: ${offline_args[*]:-(none)}" | tee "$results"
printf "%-8s %4s %8s %9s %12s %11s %10s\n" sensor seed ate_m drift_% "rot_deg/100m" aloam_ate_m aloam_rot |
  tee -a "$results"
with_peer=0
peer_ready && with_peer=1
export WITH_KITTI=$with_peer
start_all=$(date +%s)
status=0
for sensor in $sensors; do
  for seed in $seeds; do
    run="$out/${sensor}_s$seed"
    mkdir -p "$run"
    if ! why=$(simulate "$run" "$sensor" urban car "$duration" "$seed" 1) ||
      ! why=$(map_and_evaluate "$run" est "$sensor" 10,20,50 "${offline_args[@]}"); then
      printf "%-8s %4s FAILED: %s\n" "$sensor" "$seed" "$why" | tee -a "$results"
      status=1
      continue
    fi
    peer_ate=not_run peer_rot=not_run
    if [ $with_peer = 1 ]; then
      if run_peer "$run" aloam "$sensor" 10,20,50 >/dev/null; then
        peer_ate=$(figure ate_rmse_m "$run/aloam.eval.txt") peer_rot=$(figure rotation_deg_per_100m "$run/aloam.eval.txt")
      else
        peer_ate=- peer_rot=-
      fi
    fi
    rm -rf "$run/sim.bag" "$run/kitti"
    printf "%-8s %4s %8s %9s %12s %11s %10s\n" "$sensor" "$seed" "$(figure ate_rmse_m "$run/est.eval.txt")" \
      "$(figure translation_drift_percent "$run/est.eval.txt")" "$(figure rotation_deg_per_100m "$run/est.eval.txt")" \
      "$peer_ate" "$peer_rot" | tee -a "$results"
  done
done
echo "# $(($(date +%s) - start_all)) s; per-run files under $out" | tee -a "$results"
exit $status

#!/usr/bin/env bash
# Hard simulated cases of issue 11 (office corridor with an L turn, sparse tunnel, yaw bursts with stops,
# stairs, throttled topics, a wide-FOV Ouster indoors): for each case and seed, simulates a bag with
# aloam_sim, maps it with aloam_offline --deskew and prints one line of figures against the simulator's
# exact ground truth. Reports only (no bounds): the figures are the "before"/"after" numbers of the issue.
#
# Usage: eval_hard_cases.sh BIN_DIR OUT_DIR [ALOAM_OFFLINE_ARGS...]
#   BIN_DIR             devel/lib/aloam_nodelet (aloam_sim, aloam_offline, aloam_eval)
#   OUT_DIR             scratch folder: per run logs, trajectories and the table (results.txt)
#   ALOAM_OFFLINE_ARGS  passed on to every aloam_offline run (e.g. --baseline)
# Environment: SEEDS (default "1 2 3"), CASES (names to run, default all), KEEP_BAGS=1 keeps the bags.
# Needs Debian's python3 (rosbag, numpy) first on PATH and the workspace's setup.bash sourced.
#
# Columns: ATE (m, after rigid alignment, aloam_eval), translation drift (%) and rotation drift
# (deg/100 m) over the case's segment lengths; the rotation drift over the segments whose two ends lie
# outside fast turns (a true yaw step above 3 deg and the 3 sweeps after: aloam_eval --skip-turns 3);
# the largest heading (yaw) error without alignment (deg); the 90th percentile of the rotation error of
# single sweep-to-sweep steps (deg); and how many estimated steps move against the true step (dot
# product < 0) among the true steps longer than 5 cm. frames / period_s are the published sweeps and the
# spacing of their stamps.
# A-LOAM's ATE and rotation drifts on the same sweeps stand beside ours (aloam_ate_m, aloam_rot,
# aloam_steady) when A-LOAM is built (check_lib.sh's run_peer: ../shared/peers/build_aloam.sh,
# ALOAM_PEER_WS); otherwise they read "not_run", and "-" where A-LOAM has no launch values for the sensor
# (Ouster).
set -uo pipefail
source "$(dirname "$0")/check_lib.sh"
need_args 2 $#
bin="$1" out="$2"
shift 2
offline_args=("$@")
seeds="${SEEDS:-1 2 3}"
mkdir -p "$out"

# name scene trajectory sensor duration_s keep_every segments_m
case_table=(
  "office_handheld    office handheld_turn   VLP16  18 1 5,10,20"
  "tunnel_car         tunnel car             VLP16  10 1 10,20,50"
  "bursts_urban       urban  handheld_bursts VLP16  18 1 5,10,20"
  "stairs_handheld    stairs handheld        VLP16  15 1 2,4,8"
  "urban_car_10hz     urban  car             VLP16  10 1 10,20,50"
  "urban_car_5hz      urban  car             VLP16  10 2 10,20,50"
  "urban_car_2hz      urban  car             VLP16  10 5 10,20,50"
  "urban_handheld_10hz urban handheld        VLP16  18 1 5,10,20"
  "urban_handheld_5hz urban  handheld        VLP16  18 2 5,10,20"
  "office_os0         office handheld_turn   OS0_64 18 1 5,10,20"
)

# steady_rotation RUN MODE SEGMENTS: rotation drift of RUN/MODE.txt over the segments outside fast turns.
steady_rotation() {
  "$bin/aloam_eval" --gt "$1/gt.txt" --trajectory "$1/$2.txt" --segments "$3" --skip-turns 3 >"$1/$2.steady.txt" 2>&1
  figure rotation_deg_per_100m "$1/$2.steady.txt"
}

results="$out/results.txt"
header=$(printf "%-20s %4s %6s %8s %8s %9s %12s %10s %11s %13s %9s %11s %10s %12s" case seed frames period_s ate_m \
  drift_% "rot_deg/100m" rot_steady max_head_deg step_rot_p90 backward aloam_ate_m aloam_rot aloam_steady)
with_peer=0
peer_ready && with_peer=1
export WITH_KITTI=$with_peer
echo "# aloam_offline extra args: ${offline_args[*]:-(none)}" | tee "$results"
echo "$header" | tee -a "$results"
start_all=$(date +%s)
status=0
for row in "${case_table[@]}"; do
  read -r name scene trajectory sensor duration keep segments <<<"$row"
  if [ -n "${CASES:-}" ] && ! grep -qw "$name" <<<"$CASES"; then
    continue
  fi
  for seed in $seeds; do
    run="$out/${name}_s$seed"
    mkdir -p "$run"
    if ! why=$(simulate "$run" "$sensor" "$scene" "$trajectory" "$duration" "$seed" "$keep") ||
      ! why=$(map_and_evaluate "$run" est "$sensor" "$segments" "${offline_args[@]}"); then
      printf "%-20s %4s FAILED: %s\n" "$name" "$seed" "$why" | tee -a "$results"
      status=1
      continue
    fi
    peer_ate=not_run peer_rot=not_run peer_steady=not_run
    if [ $with_peer = 1 ]; then
      if run_peer "$run" aloam "$sensor" "$segments" >/dev/null; then
        peer_ate=$(figure ate_rmse_m "$run/aloam.eval.txt") peer_rot=$(figure rotation_deg_per_100m "$run/aloam.eval.txt")
        peer_steady=$(steady_rotation "$run" aloam "$segments")
      else
        peer_ate=- peer_rot=- peer_steady=-
      fi
    fi
    [ "${KEEP_BAGS:-0}" = 1 ] || rm -rf "$run/sim.bag" "$run/kitti"
    printf "%-20s %4s %6s %8s %8s %9s %12s %10s %11s %13s %9s %11s %10s %12s\n" "$name" "$seed" "$(field frames "$run/gt_info.txt")" \
      "$(field period_s "$run/gt_info.txt")" "$(figure ate_rmse_m "$run/est.eval.txt")" \
      "$(figure translation_drift_percent "$run/est.eval.txt")" "$(figure rotation_deg_per_100m "$run/est.eval.txt")" \
      "$(steady_rotation "$run" est "$segments")" "$(field max_heading_deg "$run/est.compare.txt")" \
      "$(field step_rot_p90_deg "$run/est.compare.txt")" \
      "$(field backward_steps "$run/est.compare.txt")/$(field of "$run/est.compare.txt")" "$peer_ate" "$peer_rot" \
      "$peer_steady" |
      tee -a "$results"
  done
done
echo "# $(($(date +%s) - start_all)) s; per-run files under $out" | tee -a "$results"
exit $status

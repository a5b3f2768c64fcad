#!/usr/bin/env bash
# Accuracy over scene families (issue 23): for each family and seed, aloam_sim draws a scene and a motion
# (`--family F --seed N`), this package maps the sweeps (aloam_offline --deskew on the bag) and, when it is
# built, A-LOAM maps the same sweeps (../shared/peers/run_aloam.sh on the KITTI-layout copy). Both are
# evaluated against the simulator's exact ground truth by the same tools, one TSV row per draw, and
# family_summary.py prints per family the median and 90th percentile of ATE and rotation drift for both,
# and how many draws are worse than A-LOAM's (and more than 20 % worse). Reports only, no bounds.
#
# Usage: eval_families.sh BIN_DIR OUT_DIR [--draws N] [--families a,b] [--first-seed S] [ALOAM_OFFLINE_ARGS...]
#   BIN_DIR             devel/lib/aloam_nodelet (aloam_sim, aloam_offline, aloam_eval)
#   OUT_DIR             scratch folder: per draw logs and trajectories, draws.tsv and summary.txt
#   --draws N           seeds per family (default 20): S, S+1, ... S+N-1 (--first-seed S, default 1)
#   --families LIST     comma-separated (default corridor,tunnel,office,stairwell,urban,field; also
#                       corridor_issue23, the fixed corridor of the issue)
#   ALOAM_OFFLINE_ARGS  passed on to every aloam_offline run (e.g. --baseline)
# Environment: SENSOR (default VLP16), DURATION (s, default 15: 150 sweeps at 10 Hz), SIM_ARGS (more
#   aloam_sim arguments for every draw, e.g. "--noise 0.003": less range noise than the default 0.01 m),
#   KEEP_BAGS=1 keeps the bags and KITTI folders, ALOAM_PEER_WS (A-LOAM's workspace, default
#   ${TMPDIR:-/tmp}/aloam_ws), ALOAM_PEERS (default ../shared/peers beside the repository), ALOAM_PEER_CACHE
#   (a folder: A-LOAM's trajectory of each draw is kept there under a checksum of the sweeps and reused when
#   the same sweeps come again).
# A-LOAM: build it once with `../shared/peers/build_aloam.sh /tmp/aloam_ws` (about 3 minutes; it installs
#   libtf-dev if missing). Without it only this package's figures are printed, and the summary says so.
# Needs Debian's python3 (rosbag, numpy) first on PATH and the workspace's setup.bash sourced.
#
# Segment lengths of the drift figures: 1/8, 1/4 and 1/2 of each draw's path (the same for both systems).
set -uo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
source "$here/check_lib.sh"
need_args 2 $#
bin="$1" out="$2"
shift 2
draws=20 first_seed=1 families="corridor,tunnel,office,stairwell,urban,field"
offline_args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --draws) draws="$2"; shift 2 ;;
    --families) families="$2"; shift 2 ;;
    --first-seed) first_seed="$2"; shift 2 ;;
    *) offline_args+=("$1"); shift ;;
  esac
done
sensor="${SENSOR:-VLP16}" duration="${DURATION:-15}"
mkdir -p "$out"
with_peer=0
if peer_ready; then
  with_peer=1
else
  echo "# A-LOAM not built ($peer_ws): not run; build it with $peers/build_aloam.sh $peer_ws" >&2
fi
export WITH_KITTI=$with_peer

tsv="$out/draws.tsv"
printf "family\tseed\tstatus\tframes\tpath_m\tours_ate_m\tours_drift_pct\tours_rot_deg_100m\tours_backward\t" >"$tsv"
printf "aloam_ate_m\taloam_drift_pct\taloam_rot_deg_100m\taloam_backward\tours_s\taloam_s\tdraw\n" >>"$tsv"
echo "# sensor $sensor, ${duration} s per draw, seeds $first_seed..$((first_seed + draws - 1)), A-LOAM $([ $with_peer = 1 ] && echo "from $peer_ws" || echo "not run")" |
  tee "$out/summary.txt"
echo "# aloam_offline extra args: ${offline_args[*]:-(none)}; aloam_sim extra args: ${SIM_ARGS:-(none)}" |
  tee -a "$out/summary.txt"
start_all=$(date +%s)
IFS=, read -r -a family_list <<<"$families"
for family in "${family_list[@]}"; do
  for seed in $(seq "$first_seed" $((first_seed + draws - 1))); do
    run="$out/${family}_s$seed"
    rm -rf "$run"
    mkdir -p "$run"
    status=ok ours=(nan nan nan nan) peer=(nan nan nan nan) ours_s=nan peer_s=nan frames=nan path=nan
    # shellcheck disable=SC2086
    if ! why=$(simulate_with "$run" --sensor "$sensor" --family "$family" --duration "$duration" --seed "$seed" \
      ${SIM_ARGS:-}); then
      status="sim_failed"
      echo "$family $seed: $why" >&2
    else
      frames=$(field frames "$run/gt_info.txt")
      path=$(awk '$1 == "sweeps" {for (i = 1; i < NF; ++i) if ($i == "path") {print $(i + 1); exit}}' "$run/sim.txt")
      segments=$(awk -v p="$path" 'BEGIN {printf "%.1f,%.1f,%.1f", p / 8, p / 4, p / 2}')
      t0=$(date +%s.%N)
      if why=$(map_and_evaluate "$run" est "$sensor" "$segments" "${offline_args[@]}"); then
        ours=("$(figure ate_rmse_m "$run/est.eval.txt")" "$(figure translation_drift_percent "$run/est.eval.txt")"
          "$(figure rotation_deg_per_100m "$run/est.eval.txt")" "$(field backward_steps "$run/est.compare.txt")")
      else
        status="ours_failed"
        echo "$family $seed: $why" >&2
      fi
      ours_s=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN {printf "%.1f", b - a}')
      if [ $with_peer = 1 ]; then
        t0=$(date +%s.%N)
        if why=$(run_peer "$run" aloam "$sensor" "$segments"); then
          peer=("$(figure ate_rmse_m "$run/aloam.eval.txt")" "$(figure translation_drift_percent "$run/aloam.eval.txt")"
            "$(figure rotation_deg_per_100m "$run/aloam.eval.txt")" "$(field backward_steps "$run/aloam.compare.txt")")
        else
          [ "$status" = ok ] && status=aloam_failed || status="$status,aloam_failed"
          echo "$family $seed: $why" >&2
        fi
        peer_s=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN {printf "%.1f", b - a}')
      fi
    fi
    draw_line=$(sed -n 's/^draw: //p' "$run/sim.txt" 2>/dev/null)
    printf "%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n" "$family" "$seed" "$status" \
      "$frames" "$path" "${ours[@]}" "${peer[@]}" "$ours_s" "$peer_s" "$draw_line" >>"$tsv"
    printf "%-17s %4s %-12s ours ATE %8s m  A-LOAM ATE %8s m  (%s s / %s s)\n" "$family" "$seed" "$status" "${ours[0]}" \
      "$([ $with_peer = 1 ] && echo "${peer[0]}" || echo "not run")" "$ours_s" "$peer_s" >&2
    [ "${KEEP_BAGS:-0}" = 1 ] || rm -rf "$run/sim.bag" "$run/kitti"
  done
done
python3 "$here/family_summary.py" "$tsv" $([ $with_peer = 1 ] || echo --no-aloam) | tee -a "$out/summary.txt"
echo "# $(($(date +%s) - start_all)) s; per-draw rows in $tsv" | tee -a "$out/summary.txt"

#!/usr/bin/env bash
# End-to-end check of the hard simulated cases of issue 11 (item 5): every case of the table below is
# simulated with aloam_sim for each seed, mapped with aloam_offline --deskew twice (the new handling, and
# --baseline: the A-LOAM-like handling of 81f6493) and evaluated against the simulator's exact ground truth.
# Prints one line per case and seed with both figures; fails when a figure of the new handling breaks its
# bound or an asserted target (TARGETS below) does not hold. Targets not met today are printed as
# "TARGET MISSED: ..." and not asserted.
#
# Usage: check_hard_cases.sh BIN_DIR OUT_DIR      (exit 0 passed, 77 skipped, else failed)
#   BIN_DIR  devel/lib/aloam_nodelet (aloam_sim, aloam_offline, aloam_eval)
# Environment: SEEDS (default "1 2 3"), CASES (names to run, default all; targets need both their cases).
# Needs Debian's python3 (rosbag, numpy) first on PATH and the workspace's setup.bash sourced.
#
# Figures: ATE (m, rigid alignment, aloam_eval), rotation drift (deg/100 m over the segments), backward:
# estimated steps against the true step among the true steps longer than 5 cm (hard_case_metrics.py).
set -uo pipefail
source "$(dirname "$0")/check_lib.sh"
need_args 2 $#
bin="$1" out="$2"
seeds="${SEEDS:-1 2 3}"
for tool in aloam_sim aloam_offline aloam_eval; do
  [ -x "$bin/$tool" ] || { echo "SKIP: $bin/$tool not built"; exit 77; }
done
python3 -c "import rosbag, numpy" 2>/dev/null || { echo "SKIP: python3 has no rosbag/numpy"; exit 77; }
mkdir -p "$out"

# One row per case (the cases and durations of eval_hard_cases.sh). Bounds are for the new handling, about
# 1.5x the worst of seeds 1-3; "-" means no bound. Measured (commit of this table, aloam_offline --deskew)
# in the comment under each row: new handling per seed 1/2/3, then the baseline (--baseline). Update
# both when the core changes (items 3-4 of issue 11 will move them).
#                      scene  trajectory      sensor dur keep segments  max_ate max_rot  max_back
case_table=(
  "office_handheld     office handheld_turn   VLP16  18  1   5,10,20    0.04    13       0"
  #   ATE 0.024/0.023/0.024 m, rot 7.0/6.8/8.5 deg/100 m, back 0/0/0 of 179 (mapping's leaves at a quarter
  #   indoors; before them 0.086/0.077/0.092 m, rot 156/109/214); baseline ATE 3.19/3.09/3.20
  "tunnel_car          tunnel car             VLP16  10  1   10,20,50   43      2.0      -"
  #   ATE 28.55/28.56/28.55 m (lost along the tunnel), rot 1.19/1.30/1.05, back 47/38/51 of 99; baseline same
  "bursts_urban        urban  handheld_bursts VLP16  18  1   5,10,20    0.14    16       -"
  #   ATE 0.091/0.073/0.066 m, rot 8.4/10.5/8.3, back 4/3/1 of 137 (sweep span; before it ATE
  #   0.111/0.072/0.072, rot 17.5/20.8/23.5; before the extra searches for hard frames 0.137/0.082/0.085,
  #   rot 25.5/26.6/29.2); baseline ATE 0.137/0.082/0.085
  "stairs_handheld     stairs handheld        VLP16  15  1   2,4,8      0.2     125      -"
  #   ATE 0.131/0.118/0.131 m, rot 77/82/76, back 0/0/0 of 149 (leaves at a quarter; before them
  #   0.227/0.292/0.281 m, rot 540/211/187); baseline ATE 2.86 (all seeds), rot 607
  "urban_car_10hz      urban  car             VLP16  10  1   10,20,50   0.12    1.2      -"
  #   ATE 0.051/0.079/0.037 m, rot 0.67/0.69/0.81, back 0; baseline same
  "urban_car_5hz       urban  car             VLP16  10  2   10,20,50   0.10    0.93     -"
  #   ATE 0.044/0.066/0.030 m (motion hypotheses; before them 0.044/0.124/0.093, rot 0.49/0.57/0.62);
  #   baseline ATE 0.036/0.129/0.089, rot 0.89/0.97/0.91
  "urban_car_2hz       urban  car             VLP16  10  5   10,20,50   0.09    4.1      -"
  #   ATE 0.034/0.055/0.023 m (motion hypotheses; before them 2.76/4.45/5.84, rot 0.96/1.46/2.76);
  #   baseline ATE 2.51/5.18/5.96, rot 3.21/3.27/3.90
  "urban_handheld_10hz urban  handheld        VLP16  18  1   5,10,20    0.11    8.5      -"
  #   ATE 0.052/0.055/0.052 m, rot 4.3/5.5/4.9, back 3/0/0 of 179 (sweep span; before it 0.070/0.044/0.051
  #   m, rot 7.4/8.7/12.5); baseline ATE 0.075/0.057/0.052
  "urban_handheld_5hz  urban  handheld        VLP16  18  2   5,10,20    0.09    10       -"
  #   ATE 0.053/0.058/0.059 m, rot 4.3/5.7/6.3 (sweep span; before it 0.113/0.062/0.076, rot 11.4/12.8/15.8;
  #   before the hypotheses and the extra searches for hard frames 0.129/0.546/0.100, rot 17.4/43.2/22.4);
  #   baseline ATE 0.276/0.202/0.198, rot 36.1/37.0/30.5
  "office_os0          office handheld_turn   OS0_64 18  1   5,10,20    0.025   9        0"
  #   ATE 0.014/0.015/0.013 m, rot 5.9/5.7/5.7, back 0/0/0 of 179 (leaves at a quarter; before them
  #   0.067/0.106/0.085 m, rot 9.5/10.0/12.4); baseline ATE 0.211/0.254/0.239
)

# The issue's targets, checked per seed. assert: fail when it does not hold; report: print TARGET MISSED
# (not met today). Kinds:
#   max CASE FIGURE LIMIT           FIGURE of CASE <= LIMIT
#   ratio CASE REF FIGURE FACTOR    FIGURE of CASE <= FACTOR x FIGURE of REF (same mode and seed)
#   better CASE FIGURE              FIGURE of the new handling < FIGURE of the baseline
targets=(
  "assert max office_handheld ate 0.3"         # corridor hand-held: ATE <= 0.3 m over 20 m (measured <= 0.024)
  "assert max office_handheld back 0"          # ... no pose moves against the direction of travel
  "assert better office_handheld ate"          # against the A-LOAM-like handling (0.02 vs 3.1-3.2 m)
  "assert max office_os0 back 0"
  "assert better office_os0 ate"               # (0.013-0.015 vs 0.21-0.25 m)
  "assert better stairs_handheld ate"          # (0.12-0.13 vs 2.86 m)
  "report max tunnel_car back 0"               # missed: the tunnel is lost along its axis (38-51 of 99)
  "report better tunnel_car ate"               # missed: 28.5 m both
  "report max bursts_urban rot 10"             # yaw bursts: rot drift <= 10 deg/100 m; seed 2 missed (10.5)
  "assert ratio urban_car_2hz urban_car_10hz ate 3"  # 2 Hz car: within 3x of 10 Hz (0.6-0.7x measured)
  "assert better urban_car_2hz ate"            # (0.02-0.06 vs 2.5-6.0 m)
  "assert ratio urban_handheld_5hz urban_handheld_10hz ate 2"  # 5 Hz hand-held: within 2x (1.0-1.1x)
  "assert better urban_handheld_5hz ate"       # (0.07-0.12 vs 0.20-0.28 m)
)

# run_mode RUN_DIR MODE SENSOR SEGMENTS [ARGS]: maps RUN_DIR/sim.bag, writes RUN_DIR/MODE.fig
# ("ate rot back steps"); on a tool failure prints it and returns 1.
run_mode() {
  local run="$1" mode="$2"
  map_and_evaluate "$@" || return 1
  echo "$(figure ate_rmse_m "$run/$mode.eval.txt") $(figure rotation_deg_per_100m "$run/$mode.eval.txt")" \
    "$(field backward_steps "$run/$mode.compare.txt") $(field of "$run/$mode.compare.txt")" >"$run/$mode.fig"
}

# value CASE SEED MODE FIGURE: a figure of a finished run (empty when the run is missing).
value() {
  local f="$out/${1}_s$2/$3.fig"
  [ -f "$f" ] || return 0
  case $4 in
    ate) awk '{print $1}' "$f" ;;
    rot) awk '{print $2}' "$f" ;;
    back) awk '{print $3}' "$f" ;;
  esac
}

start_all=$(date +%s)
status=0
printf "%-20s %4s %6s | %-27s | %-27s | %s\n" case seed frames "new: ate_m rot_deg/100m back" \
  "baseline: ate_m rot back" "both runs"
for row in "${case_table[@]}"; do
  read -r name scene trajectory sensor duration keep segments max_ate max_rot max_back <<<"$row"
  if [ -n "${CASES:-}" ] && ! grep -qw "$name" <<<"$CASES"; then
    continue
  fi
  for seed in $seeds; do
    run="$out/${name}_s$seed"
    rm -rf "$run"
    mkdir -p "$run"
    if ! why=$(simulate "$run" "$sensor" "$scene" "$trajectory" "$duration" "$seed" "$keep"); then
      echo "FAIL: $name seed $seed: $why"
      status=1
      continue
    fi
    t0=$(date +%s)
    why=$(run_mode "$run" new "$sensor" "$segments") ||
      { echo "FAIL: $name seed $seed: new handling: $why"; status=1; continue; }
    why=$(run_mode "$run" baseline "$sensor" "$segments" --baseline) ||
      { echo "FAIL: $name seed $seed: baseline: $why"; status=1; continue; }
    t1=$(date +%s)
    rm -f "$run/sim.bag"
    read -r ate rot back steps <"$run/new.fig"
    read -r bate brot bback bsteps <"$run/baseline.fig"
    printf "%-20s %4s %4sfr | %8s %10s %7s | %8s %10s %7s | %ss\n" "$name" "s$seed" \
      "$(field frames "$run/gt_info.txt")" "$ate" "$rot" "$back/$steps" "$bate" "$brot" "$bback/$bsteps" "$((t1 - t0))"
    [ "$max_ate" = - ] || at_most "$name seed $seed ATE (m)" "$ate" "$max_ate" || status=1
    [ "$max_rot" = - ] || at_most "$name seed $seed rotation drift (deg/100 m)" "$rot" "$max_rot" || status=1
    [ "$max_back" = - ] || at_most "$name seed $seed backward steps" "$back" "$max_back" || status=1
  done
done

for target in "${targets[@]}"; do
  read -r how kind a b c d <<<"$target"
  for seed in $seeds; do
    case $kind in
      max) v=$(value "$a" "$seed" new "$b") limit=$c what="$a $b" ;;
      ratio) v=$(value "$a" "$seed" new "$c") r=$(value "$b" "$seed" new "$c")
        limit=$(awk -v r="$r" -v f="$d" 'BEGIN {if (r != "") print r * f}') what="$a $c (${d}x $b: $r)" ;;
      better) v=$(value "$a" "$seed" new "$b") limit=$(value "$a" "$seed" baseline "$b") what="$a $b vs baseline" ;;
    esac
    if [ -z "$v" ] || [ -z "$limit" ]; then continue; fi  # a case not run (CASES) or failed above
    if [ "$kind" = better ]; then
      ok=$(awk -v v="$v" -v m="$limit" 'BEGIN {print (v < m) ? 1 : 0}')
    else
      ok=$(awk -v v="$v" -v m="$limit" 'BEGIN {print (v <= m) ? 1 : 0}')
    fi
    if [ "$ok" = 1 ]; then
      echo "target met: $what seed $seed: $v (limit $limit)"
    elif [ "$how" = assert ]; then
      echo "FAIL: target $what seed $seed: $v (limit $limit)"
      status=1
    else
      echo "TARGET MISSED: $what seed $seed: $v (target $limit)"
    fi
  done
done
echo "# $(($(date +%s) - start_all)) s; per-run files under $out"
[ $status -eq 0 ] && echo "PASSED hard cases check"
exit $status

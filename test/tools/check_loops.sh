#!/usr/bin/env bash
# Loop closure on the simulator's looping families (issue 24): each draw is simulated with aloam_sim
# --family, mapped with aloam_offline --deskew without and with --loop-closure, and evaluated against the
# exact ground truth (aloam_eval ATE, the end pose against the truth, loop_truth.py: every accepted loop
# against the true relative pose, false beyond 0.5 m or 2 deg). One line per draw. Fails on a false loop,
# on a loop_block or loop_eight draw that closes no loop (loop_floor's corridor loops leave roll weak and
# are turned away: printed as NO LOOP CLOSED), or on one whose ATE with loop closure exceeds
# 1.5 times the ATE without (+ 1 cm; any worse ATE is printed as WORSE WITH LOOP CLOSURE); the issue's
# targets (ATE at most a quarter, end within 0.3 m) are printed as TARGET MISSED when not met.
#
# Usage: check_loops.sh BIN_DIR OUT_DIR      (exit 0 passed, 77 skipped, else failed)
#   BIN_DIR  devel/lib/aloam_nodelet (aloam_sim, aloam_offline, aloam_eval)
# Environment: DRAWS ("family:seed ...", default the short sample below), DURATION (s, default 60),
#   SENSOR (default VLP16). Needs Debian's python3 (rosbag, numpy) first on PATH.
set -uo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
source "$here/check_lib.sh"
need_args 2 $#
bin="$1" out="$2"
draws="${DRAWS:-loop_block:1 loop_eight:1 loop_floor:1 loop_repetitive:1 loop_repetitive:2}"
duration="${DURATION:-60}" sensor="${SENSOR:-VLP16}"
for tool in aloam_sim aloam_offline aloam_eval; do
  [ -x "$bin/$tool" ] || { echo "SKIP: $bin/$tool not built"; exit 77; }
done
python3 -c "import rosbag, numpy" 2>/dev/null || { echo "SKIP: python3 has no rosbag/numpy"; exit 77; }
mkdir -p "$out"
status=0
printf "%-16s %4s %6s %9s %9s %8s %8s %6s %6s %6s\n" family seed frames ate_off_m ate_on_m end_off end_on loops false tried |
  tee "$out/summary.txt"
for draw in $draws; do
  family="${draw%%:*}" seed="${draw##*:}"
  run="$out/$family-$seed"
  mkdir -p "$run"
  if ! simulate_with "$run" --sensor "$sensor" --family "$family" --duration "$duration" --seed "$seed"; then
    echo "FAIL: $family seed $seed: could not simulate"; status=1; continue
  fi
  segments=10,20,50
  if ! map_and_evaluate "$run" off "$sensor" "$segments" ||
    ! map_and_evaluate "$run" on "$sensor" "$segments" --loop-closure --loops "$run/loops.tsv"; then
    echo "FAIL: $family seed $seed: could not map or evaluate"; status=1; continue
  fi
  python3 "$here/loop_truth.py" "$run/loops.tsv" "$run/gt.txt" "$run/on.txt" >"$run/loops.check.txt" 2>&1 ||
    { echo "FAIL: $family seed $seed: loop_truth.py (see $run/loops.check.txt)"; status=1; continue; }
  python3 "$here/loop_truth.py" /dev/null "$run/gt.txt" "$run/off.txt" >"$run/off.check.txt" 2>&1 || true
  ate_off=$(figure ate_rmse_m "$run/off.eval.txt") ate_on=$(figure ate_rmse_m "$run/on.eval.txt")
  summary=$(tail -1 "$run/loops.check.txt")
  accepted=$(field accepted "$run/loops.check.txt") false=$(field false "$run/loops.check.txt")
  tried=$(field tried "$run/loops.check.txt")
  end_on=$(field end_error_m "$run/loops.check.txt") end_off=$(field end_error_m "$run/off.check.txt")
  frames=$(grep -c . "$run/gt.txt")
  printf "%-16s %4s %6s %9s %9s %8s %8s %6s %6s %6s\n" "$family" "$seed" "$frames" "$ate_off" "$ate_on" "$end_off" \
    "$end_on" "$accepted" "$false" "$tried" | tee -a "$out/summary.txt"
  [ "${false:-1}" = 0 ] || { echo "FAIL: $family seed $seed: false loops accepted ($summary)"; grep false "$run/loops.check.txt"; status=1; }
  if [ "$family" != loop_repetitive ]; then
    if [ "${accepted:-0}" -eq 0 ]; then
      if [ "$family" = loop_floor ]; then
        echo "NO LOOP CLOSED: $family seed $seed (its registrations leave roll weak: rejected, docs/loop_closure.md)"
      else
        echo "FAIL: $family seed $seed: no loop closed"; status=1
      fi
    fi
    at_most "$family seed $seed: ATE with loop closure (m)" "$ate_on" "$(awk -v a="$ate_off" 'BEGIN {print 1.5 * a + 0.01}')" ||
      status=1
    awk -v a="$ate_on" -v b="$ate_off" 'BEGIN {exit !(a > b)}' &&
      echo "WORSE WITH LOOP CLOSURE: $family seed $seed: ATE $ate_on m, $ate_off m without"
    awk -v a="$ate_on" -v b="$ate_off" 'BEGIN {exit !(a <= 0.25 * b)}' ||
      echo "TARGET MISSED: $family seed $seed: ATE $ate_on m with loop closure, not at most a quarter of $ate_off m"
    awk -v e="$end_on" 'BEGIN {exit !(e <= 0.3)}' ||
      echo "TARGET MISSED: $family seed $seed: end $end_on m from the truth (target 0.3 m)"
  fi
done
[ $status -eq 0 ] && echo "PASSED loop closure check ($(echo $draws | wc -w) draws)"
exit $status

# Shared by the end-to-end check scripts in this folder. Source it.

# need_args MIN COUNT: unless COUNT (the script's $#) is at least MIN, prints the script's header comment
# (its usage) to stderr and exits 2.
need_args() {
  [ "$2" -ge "$1" ] && return 0
  sed -n '2,/^[^#]/{/^#/p}' "$0" >&2
  exit 2
}

# The value of `key: value` in FILE (as aloam_eval prints its headline figures).
figure() { awk -v k="$1:" '$1 == k {print $2}' "$2"; }

# at_most LABEL VALUE LIMIT: prints a failure and returns 1 unless VALUE is a number <= LIMIT.
at_most() {
  awk -v v="$2" -v m="$3" 'BEGIN {exit !(v != "" && v + 0 == v && v <= m)}' && return 0
  echo "FAIL: $1 $2 > $3"
  return 1
}

# The value after the word KEY in FILE (as hard_case_metrics.py prints them: `key value key value ...`).
field() { awk -v k="$1" '{for (i = 1; i < NF; ++i) if ($i == k) {print $(i + 1); exit}}' "$2"; }

# The simulated runs of eval_hard_cases.sh, eval_sensor_suite.sh and check_hard_cases.sh. Both functions
# use the caller's $bin (aloam_sim, aloam_offline, aloam_eval) and this folder's hard_case_metrics.py, and
# on a failure print the step that failed (with its log) and return 1.
hard_case_metrics="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/hard_case_metrics.py"

# simulate RUN SENSOR SCENE TRAJECTORY DURATION_S SEED KEEP_EVERY: RUN/sim.bag (log RUN/sim.txt) and its
# ground truth RUN/gt.txt (RUN/gt_info.txt: `frames N period_s P`).
simulate() {
  local run="$1"
  "$bin/aloam_sim" --sensor "$2" --scene "$3" --trajectory "$4" --duration "$5" --seed "$6" --keep-every "$7" \
    --bag "$run/sim.bag" >"$run/sim.txt" 2>&1 || { echo "aloam_sim (see $run/sim.txt)"; return 1; }
  python3 "$hard_case_metrics" gt "$run/sim.bag" "$run/gt.txt" >"$run/gt_info.txt" 2>&1 ||
    { echo "ground truth (see $run/gt_info.txt)"; return 1; }
}

# map_and_evaluate RUN MODE SENSOR SEGMENTS [ALOAM_OFFLINE_ARGS...]: maps RUN/sim.bag with aloam_offline
# --deskew into RUN/MODE.txt (log RUN/MODE.offline.txt) and compares it with RUN/gt.txt: aloam_eval over
# the SEGMENTS lengths (m, comma-separated) into RUN/MODE.eval.txt, hard_case_metrics.py compare (heading
# error, backward steps) into RUN/MODE.compare.txt.
map_and_evaluate() {
  local run="$1" mode="$2" sensor="$3" segments="$4"
  shift 4
  "$bin/aloam_offline" --bag "$run/sim.bag" --topic velodyne_points --sensor "$sensor" --deskew \
    --trajectory "$run/$mode.txt" "$@" >"$run/$mode.offline.txt" 2>&1 ||
    { echo "aloam_offline (see $run/$mode.offline.txt)"; return 1; }
  "$bin/aloam_eval" --gt "$run/gt.txt" --trajectory "$run/$mode.txt" --segments "$segments" \
    >"$run/$mode.eval.txt" 2>&1 || { echo "aloam_eval (see $run/$mode.eval.txt)"; return 1; }
  python3 "$hard_case_metrics" compare "$run/gt.txt" "$run/$mode.txt" >"$run/$mode.compare.txt" 2>&1 ||
    { echo "hard_case_metrics.py compare (see $run/$mode.compare.txt)"; return 1; }
}

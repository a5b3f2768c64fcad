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

# simulate RUN SENSOR SCENE TRAJECTORY DURATION_S SEED KEEP_EVERY [ALOAM_SIM_ARGS...]: RUN/sim.bag (log
# RUN/sim.txt) and its ground truth RUN/gt.txt (RUN/gt_info.txt: `frames N period_s P`). With
# WITH_KITTI=1 also the sweeps in KITTI layout under RUN/kitti (for A-LOAM, see run_peer).
simulate() {
  local run="$1"
  simulate_with "$run" --sensor "$2" --scene "$3" --trajectory "$4" --duration "$5" --seed "$6" --keep-every "$7" \
    "${@:8}"
}

# simulate_with RUN ALOAM_SIM_ARGS...: as simulate, with aloam_sim's arguments given whole (e.g. --family).
simulate_with() {
  local run="$1"
  shift
  local kitti=()
  [ "${WITH_KITTI:-0}" = 1 ] && kitti=(--kitti "$run/kitti")
  "$bin/aloam_sim" "$@" "${kitti[@]}" --bag "$run/sim.bag" >"$run/sim.txt" 2>&1 ||
    { echo "aloam_sim (see $run/sim.txt)"; return 1; }
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
  evaluate "$run" "$mode" "$segments"
}

# evaluate RUN MODE SEGMENTS: RUN/MODE.txt against RUN/gt.txt, as map_and_evaluate does.
evaluate() {
  local run="$1" mode="$2" segments="$3"
  "$bin/aloam_eval" --gt "$run/gt.txt" --trajectory "$run/$mode.txt" --segments "$segments" \
    >"$run/$mode.eval.txt" 2>&1 || { echo "aloam_eval (see $run/$mode.eval.txt)"; return 1; }
  python3 "$hard_case_metrics" compare "$run/gt.txt" "$run/$mode.txt" >"$run/$mode.compare.txt" 2>&1 ||
    { echo "hard_case_metrics.py compare (see $run/$mode.compare.txt)"; return 1; }
}

# A-LOAM beside this package (issue 23). The reference A-LOAM lives in ../shared/peers beside the repository
# (ALOAM_PEERS overrides); build it once with `$peers/build_aloam.sh WS` (about 3 minutes) and point
# ALOAM_PEER_WS at WS (default: build_aloam.sh's default workspace, ${TMPDIR:-/tmp}/aloam_ws).
aloam_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
peers="${ALOAM_PEERS:-$aloam_root/../shared/peers}"
peer_ws="${ALOAM_PEER_WS:-${TMPDIR:-/tmp}/aloam_ws}"

# peer_ready: true when A-LOAM is built (then run_peer works).
peer_ready() { [ -x "$peer_ws/devel/lib/aloam_velodyne/alaserMapping" ] && [ -x "$peers/run_aloam.sh" ]; }

# run_peer RUN MODE SENSOR SEGMENTS: A-LOAM on RUN/kitti/velodyne (simulate with WITH_KITTI=1) into
# RUN/MODE.txt (log RUN/MODE.run.txt), with A-LOAM's own launch values for the sensor's beam count
# (scan_line 16 / 32 / 64, and its minimum range and leaf sizes), then evaluated as evaluate does.
run_peer() {
  local run="$1" mode="$2" sensor="$3" segments="$4" values
  case "$sensor" in
    VLP16) values="16 0.3 0.2 0.4" ;;
    HDL32 | VLP32C) values="32 0.3 0.2 0.4" ;;
    HDL64) values="64 5 0.4 0.8" ;;
    *) echo "A-LOAM has no launch values for $sensor"; return 1 ;;
  esac
  # With ALOAM_PEER_CACHE=DIR, A-LOAM's trajectory is kept under a checksum of the exact sweeps and its
  # values, and reused when the same sweeps come again (A-LOAM in lockstep is deterministic); it is
  # evaluated afresh either way.
  local key="" cached=""
  if [ -n "${ALOAM_PEER_CACHE:-}" ]; then
    key=$( (cat "$run"/kitti/velodyne/*.bin; echo "$values") | md5sum | cut -d' ' -f1)
    cached="$ALOAM_PEER_CACHE/$key.txt"
  fi
  if [ -n "$cached" ] && [ -s "$cached" ]; then
    cp "$cached" "$run/$mode.txt"
    echo "reused A-LOAM's trajectory for the same sweeps from $cached" >"$run/$mode.run.txt"
  else
    # shellcheck disable=SC2086
    ALOAM_WS="$peer_ws" "$peers/run_aloam.sh" "$run/kitti/velodyne" "$run/$mode.txt" $values >"$run/$mode.run.txt" 2>&1 ||
      { echo "A-LOAM (see $run/$mode.run.txt)"; return 1; }
    [ -s "$run/$mode.txt" ] || { echo "A-LOAM wrote no pose (see $run/$mode.run.txt)"; return 1; }
    [ -z "$cached" ] || { mkdir -p "$ALOAM_PEER_CACHE" && cp "$run/$mode.txt" "$cached"; }
  fi
  evaluate "$run" "$mode" "$segments"
}

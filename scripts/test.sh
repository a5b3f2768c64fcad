#!/usr/bin/env bash
# Installs the Debian packages, checks that their list covers everything the project uses, builds (warnings
# are errors), and runs every test: gtest suites, rostests and the end-to-end checks (formatting, the
# self-check catching a missing package, the install space, the tools). Exits non-zero if anything fails.
set -euo pipefail
source "$(dirname "$0")/common.sh"

aloam_install_deps
# Before anything else: the project's own dependency list must cover what it uses (scripts/check_deps.py).
aloam_log "dependency self-check"
aloam_check_deps || { aloam_log "FAILED: the dependency self-check (see above)"; echo "0 passed, 1 failed, 0 skipped"; exit 1; }
aloam_build -DALOAM_WERROR=ON
aloam_source_ws

results="$ALOAM_WS/build/test_results"
rm -rf "$results"
aloam_log "building the tests"
# On every core here: run_tests below builds what is missing at its own -j1.
(cd "$ALOAM_WS" && catkin_make tests -j"$(nproc)" >&2)
# The sanitized checks at the end compile the core three more times and the nodelets once more (about a
# third of the run on two cores). Those builds start now, in a process group of their own at SCHED_IDLE, so
# they take only what the rostests and tool checks below leave idle (about one core of two). Each of those
# checks builds again whatever is missing or stale, so a failed background build is reported by its check.
checks_out="$ALOAM_WS/test_output"
mkdir -p "$checks_out"
prebuild_log="$checks_out/sanitized_builds.log"
idle=(chrt --idle 0)
"${idle[@]}" true 2>/dev/null || idle=(nice -n 19)
aloam_log "building the sanitized checks in the background, on idle time (log: $prebuild_log)"
# In the order the checks run; each leaves OUT_DIR.built when its build is over (built or not), so that
# its check can start while the later ones are still building.
rm -f "$checks_out"/*.built
setsid "${idle[@]}" bash -c 'for check in fuzz/run_fuzz.sh:fuzz sanitize/run_sanitized_core_tests.sh:sanitize \
    sanitize/run_tsan_core_tests.sh:tsan_core sanitize/run_tsan_nodelet_pipeline.sh:tsan_nodelets; do
    status=0
    bash "$0/test/${check%%:*}" "$1/${check##*:}" --build-only || status=$?
    # 77: the check will report its own skip (no clang for the fuzzers).
    [ $status -eq 0 ] || [ $status -eq 77 ] || echo "FAILED building ${check%%:*}"
    touch "$1/${check##*:}.built"
  done' "$ALOAM_ROOT" "$checks_out" >"$prebuild_log" 2>&1 &
prebuild=$!
trap 'kill -- -$prebuild 2>/dev/null || true' EXIT
# prebuilt NAME: waits until the background build of check NAME is over, or all of them are.
prebuilt() {
  aloam_log "waiting for the background build of $1"
  while [ ! -e "$checks_out/$1.built" ] && kill -0 "$prebuild" 2>/dev/null; do sleep 2; done
}
aloam_log "running the catkin test suites"
# run_tests exits 0 even when tests fail: catkin_test_results below gives the real status.
(cd "$ALOAM_WS" && catkin_make run_tests -j1 >&2) || true
# (Not `tee /dev/stderr`: where stderr is a file, reopening it truncates the log written so far.)
report=$(catkin_test_results --verbose "$results" || true)
echo "$report" >&2
summary=$(echo "$report" | grep '^Summary:' || true)
catkin_status=0
catkin_test_results "$results" >/dev/null || catkin_status=1
# "Summary: N tests, E errors, F failures, S skipped"
read -r total errors failures skipped < <(echo "$summary" | awk '{gsub(",", ""); print $2, $4, $6, $8}')
total=${total:-0} errors=${errors:-0} failures=${failures:-0} skipped=${skipped:-0}
[ "$total" -gt 0 ] || { aloam_log "no test results found"; catkin_status=1; }

aloam_log "running the end-to-end tool checks"
tools_passed=0 tools_failed=0 tools_skipped=0
bin="$ALOAM_WS/devel/lib/aloam_nodelet"
run_check() {  # run_check SCRIPT ARGS... (SCRIPT relative to test/): exit 0 passed, 77 skipped, else failed
  local status=0
  aloam_log "check $1"
  bash "$ALOAM_ROOT/test/$1" "${@:2}" || status=$?
  case $status in
    0) tools_passed=$((tools_passed + 1)) ;;
    77) tools_skipped=$((tools_skipped + 1)) ;;
    *) tools_failed=$((tools_failed + 1)); aloam_log "FAILED: $1" ;;
  esac
}
run_check tools/check_format.sh
run_check tools/check_param_tables.sh
run_check tools/check_deps_catch.sh
run_check tools/check_deps_files.sh
run_check tools/check_install_space.sh "$checks_out/install_space"
run_check tools/check_offline_bag.sh "$bin" "$checks_out/offline_bag"
run_check tools/check_offline_kitti.sh "$bin" "$ALOAM_DATA/kitti00_101" "$checks_out/offline_kitti"
run_check tools/check_localization_kitti.sh "$bin" "$ALOAM_DATA/kitti00_101" "$checks_out/localization_kitti"
run_check tools/check_hard_cases.sh "$bin" "$checks_out/hard_cases"
run_check tools/check_loops.sh "$bin" "$checks_out/loops"
run_check tools/check_graph.sh "$bin" "$checks_out/graph"
# Each sanitized check starts when its own build is over; the later builds go on in the idle time it
# leaves (the fuzzers keep one core busy, ThreadSanitizer's tests about 1.4).
prebuilt fuzz
run_check fuzz/run_fuzz.sh "$checks_out/fuzz" 45
prebuilt sanitize
run_check sanitize/run_sanitized_core_tests.sh "$checks_out/sanitize"
prebuilt tsan_core
run_check sanitize/run_tsan_core_tests.sh "$checks_out/tsan_core"
prebuilt tsan_nodelets
run_check sanitize/run_tsan_nodelet_pipeline.sh "$checks_out/tsan_nodelets"
wait "$prebuild" || true
grep '^FAILED' "$prebuild_log" >&2 || true
# Last, alone: beside the background builds it took 7.7 min instead of about 4 (its idle-time lanes share
# SCHED_IDLE with them), and the builds gained little.
run_check longrun/run_long_drive.sh "$bin" "$checks_out/long_drive" "${ALOAM_LONG_DRIVE_SWEEPS:-18000}"

passed=$((total - errors - failures - skipped + tools_passed))
failed=$((errors + failures + tools_failed))
echo "$passed passed, $failed failed, $((skipped + tools_skipped)) skipped"
[ $catkin_status -eq 0 ] && [ $tools_failed -eq 0 ]

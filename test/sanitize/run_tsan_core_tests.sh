#!/usr/bin/env bash
# Builds the ROS-free core and its gtest suite with ThreadSanitizer (outside catkin: the core needs no ROS)
# and runs it. Every stage runs its searches on 2 threads by default (the configs' `threads`), so the
# stage, pipeline and parallel tests all exercise the helper threads.
# Usage: run_tsan_core_tests.sh OUT_DIR [--build-only]. Exit 0: passed and ThreadSanitizer reported nothing
# (with --build-only: built); 1: it did not build, a test failed or ThreadSanitizer reported.
# The build (and which tests are in it) is shared with run_sanitized_core_tests.sh: sanitize_common.sh.
set -euo pipefail
out="$1"
root="$(cd "$(dirname "$0")/../.." && pwd)"
source "$root/test/sanitize/sanitize_common.sh"
mapfile -t command < <(sanitize_command "$root" g++ -fsanitize=thread)
sanitize_build_core_tests "$root" "$out" test_core_tsan tsan_tests "${command[@]}" || exit 1
[ "${2:-}" != --build-only ] || exit 0

log="$out/test_core_tsan.log"
start=$SECONDS
status=0
TSAN_OPTIONS="$(tsan_options "$root")" sanitize_run_sharded "$log" "$out/test_core_tsan" --gtest_brief=1 \
  --gtest_filter="$(tsan_gtest_filter)" || status=$?
grep -E '^\[  (PASSED|FAILED)  \]' "$log" || true
echo "ran the core tests under ThreadSanitizer in $((SECONDS - start)) s (log: $log)"
reports=$(tsan_reports "$log")
if [ "$status" -ne 0 ] || [ "$reports" -ne 0 ]; then
  echo "FAILED core tests under ThreadSanitizer: exit $status, $reports reports (see $log)"
  exit 1
fi
echo "PASSED core tests under ThreadSanitizer (no report)"

#!/usr/bin/env bash
# Builds the ROS-free core and its gtest suite with AddressSanitizer and UndefinedBehaviorSanitizer
# (outside catkin: the core needs no ROS) and runs it.
# Usage: run_sanitized_core_tests.sh OUT_DIR [--build-only].
# Exit 0: passed (with --build-only: built); non-zero: it did not build, a test failed or a sanitizer reported.
# The build (and which tests are in it) is shared with run_tsan_core_tests.sh: sanitize_common.sh.
set -euo pipefail
out="$1"
root="$(cd "$(dirname "$0")/../.." && pwd)"
source "$root/test/sanitize/sanitize_common.sh"
mapfile -t command < <(sanitize_command "$root" g++ -fsanitize=address,undefined -fno-sanitize-recover=undefined)
sanitize_build_core_tests "$root" "$out" test_core_sanitized tests "${command[@]}" || exit 1
[ "${2:-}" != --build-only ] || exit 0
log="$out/test_core_sanitized.log"
start=$SECONDS
status=0
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  sanitize_run_sharded "$log" "$out/test_core_sanitized" --gtest_brief=1 --gtest_filter="$(sanitize_gtest_filter)" ||
  status=$?
grep -E '^\[  (PASSED|FAILED)  \]' "$log" || true
echo "ran the core tests under AddressSanitizer + UndefinedBehaviorSanitizer in $((SECONDS - start)) s (log: $log)"
if [ "$status" -ne 0 ]; then
  grep -m 1 -A 40 -E 'ERROR: AddressSanitizer|runtime error:|^\[  FAILED  \]' "$log" || tail -n 40 "$log"
  echo "FAILED core tests under AddressSanitizer + UndefinedBehaviorSanitizer: exit $status (see $log)"
  exit 1
fi
echo "PASSED core tests under AddressSanitizer + UndefinedBehaviorSanitizer"

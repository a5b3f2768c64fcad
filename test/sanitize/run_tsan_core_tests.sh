#!/usr/bin/env bash
# Builds the ROS-free core and its gtest suite with ThreadSanitizer (outside catkin: the core needs no ROS)
# and runs it. Every stage runs its searches on 2 threads by default (the configs' `threads`), so the
# stage, pipeline and parallel tests all exercise the helper threads. Usage: run_tsan_core_tests.sh OUT_DIR.
# Exit 0: passed and ThreadSanitizer reported nothing; 1: a test failed or ThreadSanitizer reported.
# Sources and tests are globbed, so new core files are checked without editing this script.
set -euo pipefail
out="$1"
root="$(cd "$(dirname "$0")/../.." && pwd)"
mkdir -p "$out/obj"
flags=(-std=c++17 -O1 -g -fno-omit-frame-pointer -fsanitize=thread
       -I "$root/include" -I /usr/include/eigen3 -I /usr/include/pcl-1.13)
# Not here: test_kitti_accuracy (real data through the dataset reader, a single-threaded accuracy check that
# takes minutes without a sanitizer) and test_param_defaults (reads the source tree's files; no threads).
shopt -s nullglob
tests=()
for src in "$root"/test/core/test_*.cpp; do
  name="$(basename "$src")"
  [[ "$name" == test_kitti_accuracy.cpp || "$name" == test_param_defaults.cpp ]] || tests+=("$src")
done
sources=("$root"/src/core/*.cpp "$root"/src/sim/*.cpp "$root"/src/eval/*.cpp "${tests[@]}")
start=$SECONDS
# Compile on every core. An object is reused only if neither its source nor any header changed since.
if [ -f "$out/obj/.stamp" ] && [ -n "$(find "$root/include" "$root/src" "$root/test/core" -name '*.h' -newer "$out/obj/.stamp")" ]; then
  rm -f "$out"/obj/*.o
fi
printf '%s\n' "${sources[@]}" | xargs -P "$(nproc)" -I{} bash -c '
  src="{}"; obj="'"$out"'/obj/$(echo "$src" | tr / _).o"
  if [ ! -f "$obj" ] || [ "$src" -nt "$obj" ]; then g++ '"${flags[*]@Q}"' -c "$src" -o "$obj"; fi'
touch "$out/obj/.stamp"
# Link the objects of today's sources only (an old object of a removed source may still be there).
objects=()
for src in "${sources[@]}"; do objects+=("$out/obj/$(echo "$src" | tr / _).o"); done
g++ "${flags[@]}" "${objects[@]}" -lceres -lglog -lpcl_common -lpcl_io -lgtest -lgtest_main -pthread -o "$out/test_core_tsan"
echo "built the core tests with ThreadSanitizer in $((SECONDS - start)) s"

# Every report is printed (halt_on_error=0) and makes the process exit 66 at the end; the log is also
# searched, since a test binary that exits on its own path could hide the exit code.
# second_deadlock_stack: lock-order reports show both acquisitions.
log="$out/test_core_tsan.log"
start=$SECONDS
status=0
TSAN_OPTIONS="halt_on_error=0 exitcode=66 second_deadlock_stack=1 history_size=7 print_suppressions=1 suppressions=$root/test/sanitize/tsan.supp" \
  "$out/test_core_tsan" --gtest_brief=1 >"$log" 2>&1 || status=$?
tail -n 3 "$log"
echo "ran the core tests under ThreadSanitizer in $((SECONDS - start)) s (log: $log)"
reports=$(grep -c '^WARNING: ThreadSanitizer' "$log" || true)
if [ "$status" -ne 0 ] || [ "$reports" -ne 0 ]; then
  grep -A3 '^SUMMARY: ThreadSanitizer' "$log" | grep '^SUMMARY' | sort | uniq -c || true
  echo "FAILED core tests under ThreadSanitizer: exit $status, $reports reports (see $log)"
  exit 1
fi
echo "PASSED core tests under ThreadSanitizer (no report)"

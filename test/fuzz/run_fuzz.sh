#!/usr/bin/env bash
# Builds the fuzzers with clang (libFuzzer, AddressSanitizer, UBSan) and runs each for a share of the
# given time: the PointCloud2 reader, and the stage messages as they arrive from another process
# (deserialized, validated, handed to the core stages; needs the generated message headers of a built
# workspace, else that fuzzer is skipped). Usage: run_fuzz.sh OUT_DIR [SECONDS | --build-only].
# Exit 0: no crash (with --build-only: built); 77: skipped (no clang); 1: failed.
set -euo pipefail
out="$1" seconds="${2:-60}" build_only=false
if [ "$seconds" = --build-only ]; then build_only=true seconds=60; fi
root="$(cd "$(dirname "$0")/../.." && pwd)"
ws="${ALOAM_WS:-$root/.catkin_ws}"
if ! command -v clang++ >/dev/null; then
  echo "SKIPPED fuzzing: clang++ not installed"
  exit 77
fi
source "$root/test/sanitize/sanitize_common.sh"
# The targets take libFuzzer's main; the objects they link (the core, the stage messages) are instrumented
# for it too (fuzzer-no-link: coverage without a second main), so the fuzzer is guided inside the stages.
# (That coverage slows the code several times over, so the sanitized core tests build a core of their own:
# docs/development.md.)
mapfile -t asan < <(sanitize_command "$root" clang++ -fsanitize=address,undefined,fuzzer-no-link \
  -fno-sanitize-recover=undefined)
ros_flags=("${asan[@]}" -isystem "$ws/devel/include")
stage_messages=false
[ -f "$ws/devel/include/aloam_nodelet/FeatureClouds.h" ] && stage_messages=true
# The reader is the smaller target: a third of the time, the stage messages the rest.
reader_seconds=$seconds
$stage_messages && reader_seconds=$(((seconds + 2) / 3))
stage_seconds=$((seconds - reader_seconds))

# build_target NAME OBJECTS... -- LIBRARIES...: links OUT_DIR/NAME from test/fuzz/NAME.cpp and OBJECTS
# unless it is newer than all of them and every header (test.sh builds first in the background, then runs
# this check).
build_target() {
  local name="$1" objects=()
  shift
  while [ $# -gt 0 ] && [ "$1" != -- ]; do objects+=("$1"); shift; done
  [ $# -eq 0 ] || shift
  if sanitize_stale "$root" "$out/$name" "$root/test/fuzz/$name.cpp" "${objects[@]}"; then
    "${ros_flags[@]}" -fsanitize=fuzzer "$root/test/fuzz/$name.cpp" "${objects[@]}" "$@" -o "$out/$name"
  fi
}

# run_target NAME WHAT SECONDS RSS_MB PREFIX: runs OUT_DIR/NAME for SECONDS on its corpus
# OUT_DIR/PREFIXcorpus; a crashing input is saved as OUT_DIR/PREFIXcrash-*. Exits the script with 1 if it
# finds one.
run_target() {
  local name="$1" what="$2" seconds="$3" rss_mb="$4" prefix="$5" status=0
  mkdir -p "$out/${prefix}corpus"
  # -rss_limit_mb: a bigger footprint than the target's cap is a bug too.
  "$out/$name" "$out/${prefix}corpus" -max_total_time="$seconds" -rss_limit_mb="$rss_mb" -print_final_stats=1 \
    -artifact_prefix="$out/$prefix" 2>&1 | tail -n 12 || status=$?
  # libFuzzer exits 77 on a crash by default, which scripts/test.sh would count as skipped: say 1.
  if [ "$status" -ne 0 ]; then
    echo "FAILED fuzzing $what: exit $status (inputs: $out/${prefix}crash-*, oom-*, timeout-*, leak-*)"
    exit 1
  fi
  echo "PASSED fuzzing $what for ${seconds} s"
}

mkdir -p "$out"
core_dir="$out/core"
mapfile -t core < <(sanitize_core_sources "$root" core)
ros=("$root/src/ros/pointcloud2_reader.cpp")
$stage_messages && ros+=("$root/src/ros/stage_messages.cpp" "$root/src/ros/conversions.cpp")
sanitize_compile "$root" "$core_dir" "${asan[@]}" -- "${core[@]}"
sanitize_compile "$root" "$out/stage_obj" "${ros_flags[@]}" -- "${ros[@]}"
mapfile -t core_objects < <(sanitize_objects "$core_dir" "$root" "${core[@]}")
mapfile -t ros_objects < <(sanitize_objects "$out/stage_obj" "$root" "${ros[@]}")

# The reader caps enormous clouds (1 GB is far above what it may keep). It may decode on an executor's
# threads (not with these small inputs, but it links the executor).
build_target fuzz_pointcloud2_reader "${ros_objects[0]}" "$(sanitize_objects "$core_dir" "$root" "$root/src/core/executor.cpp")" \
  -- -pthread
$build_only || run_target fuzz_pointcloud2_reader "the PointCloud2 reader" "$reader_seconds" 1024 ""

if ! $stage_messages; then
  echo "SKIPPED fuzzing the stage messages: no generated messages in $ws/devel/include (build first)"
  exit 0
fi
# The core stages and the message conversions, deserialized as they arrive from another process.
build_target fuzz_stage_messages "${core_objects[@]}" "${ros_objects[@]}" \
  -- -lceres -lglog -lpcl_io -lpcl_common -lroscpp_serialization -lrostime -lcpp_common -lpthread
$build_only || run_target fuzz_stage_messages "the stage messages" "$stage_seconds" 2048 stage_

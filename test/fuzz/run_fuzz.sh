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
# The fuzz targets take libFuzzer's main; the objects they link (stage messages) are instrumented for it
# too (fuzzer-no-link: coverage without a second main), so the fuzzer is guided inside the stages.
object_flags=(-std=c++17 -g1 -O1 -fsanitize=address,undefined,fuzzer-no-link -fno-sanitize-recover=undefined
  -I "$root/include" -isystem /usr/include/eigen3 -isystem /usr/include/pcl-1.13)
flags=("${object_flags[@]}" -fsanitize=fuzzer)
stage_messages=false
[ -f "$ws/devel/include/aloam_nodelet/FeatureClouds.h" ] && stage_messages=true
# The reader is the smaller target: a third of the time, the stage messages the rest.
reader_seconds=$seconds
$stage_messages && reader_seconds=$(((seconds + 2) / 3))
stage_seconds=$((seconds - reader_seconds))

# build_target NAME INPUTS...: links OUT_DIR/NAME from test/fuzz/NAME.cpp and INPUTS (more sources,
# objects, libraries) unless it is newer than its sources, objects and every header (test.sh builds first
# in the background, then runs this check).
build_target() {
  local name="$1" input stale=false
  shift
  [ -f "$out/$name" ] || stale=true
  for input in "$root/test/fuzz/$name.cpp" "$@"; do
    if [ -f "$input" ] && [ "$input" -nt "$out/$name" ]; then stale=true; fi
  done
  if ! $stale && [ -n "$(find "$root/include" -name '*.h' -newer "$out/$name" | head -n 1)" ]; then stale=true; fi
  if $stale; then clang++ "${flags[@]}" "$root/test/fuzz/$name.cpp" "$@" -o "$out/$name"; fi
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

# Targets and objects are kept in OUT_DIR and rebuilt when a source or any header is newer, or when the
# flags changed (the first build takes minutes).
mkdir -p "$out/stage_obj"
if [ "$(cat "$out/stage_obj/.flags" 2>/dev/null)" != "${object_flags[*]}" ]; then
  rm -f "$out"/stage_obj/*.o "$out/fuzz_pointcloud2_reader" "$out/fuzz_stage_messages"
  printf '%s' "${object_flags[*]}" >"$out/stage_obj/.flags"
fi

# The reader caps enormous clouds (1 GB is far above what it may keep). It may decode on an executor's
# threads (not with these small inputs, but it links the executor).
build_target fuzz_pointcloud2_reader "$root/src/ros/pointcloud2_reader.cpp" "$root/src/core/executor.cpp" -pthread
$build_only || run_target fuzz_pointcloud2_reader "the PointCloud2 reader" "$reader_seconds" 1024 ""

if ! $stage_messages; then
  echo "SKIPPED fuzzing the stage messages: no generated messages in $ws/devel/include (build first)"
  exit 0
fi
# The core stages and the message conversions, instrumented too (two at a time: the machine is shared).
sources=("$root"/src/core/*.cpp "$root/src/ros/stage_messages.cpp" "$root/src/ros/conversions.cpp"
  "$root/src/ros/pointcloud2_reader.cpp")
objects=() stale=()
for src in "${sources[@]}"; do
  obj="$out/stage_obj/$(basename "$src" .cpp).o"
  objects+=("$obj")
  if [ ! -f "$obj" ] || [ "$src" -nt "$obj" ] || [ -n "$(find "$root/include" -newer "$obj" -name '*.h' | head -n 1)" ]; then
    stale+=("$src")
  fi
done
# xargs hands each job one stale source after the flags ($0: the object folder).
[ ${#stale[@]} -eq 0 ] || printf '%s\n' "${stale[@]}" | xargs -d '\n' -n 1 -P 2 bash -c \
  'clang++ "${@:1:$#-1}" -c "${*: -1}" -o "$0/$(basename "${*: -1}" .cpp).o"' "$out/stage_obj" \
  "${object_flags[@]}" -isystem "$ws/devel/include"
# Only the objects of today's sources are linked (an old object of a removed source may still be there).
build_target fuzz_stage_messages -isystem "$ws/devel/include" "${objects[@]}" \
  -lceres -lglog -lpcl_io -lpcl_common -lroscpp_serialization -lrostime -lcpp_common -lpthread
$build_only || run_target fuzz_stage_messages "the stage messages" "$stage_seconds" 2048 stage_

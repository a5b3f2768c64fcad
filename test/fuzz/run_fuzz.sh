#!/usr/bin/env bash
# Builds the fuzzers with clang (libFuzzer, AddressSanitizer, UBSan) and runs each for a share of the
# given time: the PointCloud2 reader, and the stage messages as they arrive from another process
# (deserialized, validated, handed to the core stages; needs the generated message headers of a built
# workspace, else that fuzzer is skipped). Usage: run_fuzz.sh OUT_DIR [SECONDS]. Exit 0: no crash;
# 77: skipped (no clang); 1: failed.
set -euo pipefail
out="$1" seconds="${2:-60}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
ws="${ALOAM_WS:-$root/.catkin_ws}"
if ! command -v clang++ >/dev/null; then
  echo "SKIPPED fuzzing: clang++ not installed"
  exit 77
fi
flags=(-std=c++17 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
  -I "$root/include" -isystem /usr/include/eigen3 -isystem /usr/include/pcl-1.13)
stage_messages=false
[ -f "$ws/devel/include/aloam_nodelet/FeatureClouds.h" ] && stage_messages=true
# The reader is the smaller target: a third of the time, the stage messages the rest.
reader_seconds=$seconds
$stage_messages && reader_seconds=$(((seconds + 2) / 3))
stage_seconds=$((seconds - reader_seconds))

mkdir -p "$out/corpus"
clang++ "${flags[@]}" \
  "$root/test/fuzz/fuzz_pointcloud2_reader.cpp" "$root/src/ros/pointcloud2_reader.cpp" \
  -o "$out/fuzz_pointcloud2_reader"
# -rss_limit_mb: the reader caps enormous clouds; a bigger footprint is a bug too.
"$out/fuzz_pointcloud2_reader" "$out/corpus" -max_total_time="$reader_seconds" -rss_limit_mb=1024 \
  -print_final_stats=1 -artifact_prefix="$out/" 2>&1 | tail -n 12
echo "PASSED fuzzing the PointCloud2 reader for ${reader_seconds} s"

if ! $stage_messages; then
  echo "SKIPPED fuzzing the stage messages: no generated messages in $ws/devel/include (build first)"
  exit 0
fi
# The core stages and the message conversions, instrumented too (two at a time: the machine is shared).
mkdir -p "$out/stage_obj" "$out/stage_corpus"
sources=("$root"/src/core/*.cpp "$root/src/ros/stage_messages.cpp" "$root/src/ros/conversions.cpp"
  "$root/src/ros/pointcloud2_reader.cpp")
# Objects are kept in OUT_DIR and rebuilt when a source or any header is newer (the first build takes minutes).
stale=()
for src in "${sources[@]}"; do
  obj="$out/stage_obj/$(basename "$src" .cpp).o"
  if [ ! -f "$obj" ] || [ "$src" -nt "$obj" ] || [ -n "$(find "$root/include" -newer "$obj" -name '*.h' | head -n 1)" ]; then
    stale+=("$src")
  fi
done
[ ${#stale[@]} -eq 0 ] || printf '%s\n' "${stale[@]}" | xargs -P 2 -I{} sh -c \
  'clang++ "$@" -fsanitize=address,undefined -fno-sanitize-recover=undefined -c "{}" -o "'"$out"'/stage_obj/$(basename {} .cpp).o"' \
  _ -std=c++17 -g -O1 -I "$root/include" -isystem "$ws/devel/include" -isystem /usr/include/eigen3 \
  -isystem /usr/include/pcl-1.13
clang++ "${flags[@]}" -isystem "$ws/devel/include" "$root/test/fuzz/fuzz_stage_messages.cpp" "$out"/stage_obj/*.o \
  -lceres -lglog -lpcl_io -lpcl_common -lroscpp_serialization -lrostime -lcpp_common -lpthread -o "$out/fuzz_stage_messages"
"$out/fuzz_stage_messages" "$out/stage_corpus" -max_total_time="$stage_seconds" -rss_limit_mb=2048 \
  -print_final_stats=1 -artifact_prefix="$out/stage_" 2>&1 | tail -n 12
echo "PASSED fuzzing the stage messages for ${stage_seconds} s"

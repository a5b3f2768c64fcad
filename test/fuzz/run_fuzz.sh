#!/usr/bin/env bash
# Builds the PointCloud2 reader fuzzer with clang (libFuzzer, AddressSanitizer, UBSan) and runs it for a
# bounded time. Usage: run_fuzz.sh OUT_DIR [SECONDS]. Exit 0: no crash; 77: skipped (no clang); 1: failed.
set -euo pipefail
out="$1" seconds="${2:-60}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
if ! command -v clang++ >/dev/null; then
  echo "SKIPPED fuzzing: clang++ not installed"
  exit 77
fi
mkdir -p "$out/corpus"
clang++ -std=c++17 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
  -I "$root/include" -I /usr/include/eigen3 -I /usr/include/pcl-1.13 \
  "$root/test/fuzz/fuzz_pointcloud2_reader.cpp" "$root/src/ros/pointcloud2_reader.cpp" \
  -o "$out/fuzz_pointcloud2_reader"
# -rss_limit_mb: the reader caps enormous clouds; a bigger footprint is a bug too.
"$out/fuzz_pointcloud2_reader" "$out/corpus" -max_total_time="$seconds" -rss_limit_mb=1024 \
  -print_final_stats=1 -artifact_prefix="$out/" 2>&1 | tail -n 12
echo "PASSED fuzzing the PointCloud2 reader for ${seconds} s"

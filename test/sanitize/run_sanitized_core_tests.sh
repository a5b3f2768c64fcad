#!/usr/bin/env bash
# Builds the ROS-free core and its gtest suite with AddressSanitizer and UndefinedBehaviorSanitizer
# (outside catkin: the core needs no ROS) and runs it. Usage: run_sanitized_core_tests.sh OUT_DIR.
# Exit 0: passed; 1: a test failed or a sanitizer reported.
set -euo pipefail
out="$1"
root="$(cd "$(dirname "$0")/../.." && pwd)"
mkdir -p "$out/obj"
flags=(-std=c++17 -O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined -fno-sanitize-recover=undefined
       -I "$root/include" -I /usr/include/eigen3 -I /usr/include/pcl-1.13)
sources=("$root"/src/core/*.cpp "$root"/src/sim/*.cpp "$root"/src/eval/*.cpp
         "$root"/test/core/test_{sensor_model,scan_registration,laser_odometry,laser_mapping,mapping_session,cube_map,voxel_filter,kd_tree,lidar_factors,pose_solver,parallel,pipeline_inputs,kitti_metrics,sim_scene,sim_trajectories,stamp_check,odometry_gap,long_drive,localizer}.cpp)
# Compile on every core. An object is reused only if neither its source nor any header changed since.
if [ -f "$out/obj/.stamp" ] && [ -n "$(find "$root/include" "$root/test/core" -name '*.h' -newer "$out/obj/.stamp")" ]; then
  rm -f "$out"/obj/*.o
fi
printf '%s\n' "${sources[@]}" | xargs -P "$(nproc)" -I{} bash -c '
  src="{}"; obj="'"$out"'/obj/$(echo "$src" | tr / _).o"
  if [ ! -f "$obj" ] || [ "$src" -nt "$obj" ]; then g++ '"${flags[*]@Q}"' -c "$src" -o "$obj"; fi'
touch "$out/obj/.stamp"
# Link the objects of today's sources only (an old object of a removed source may still be there).
objects=()
for src in "${sources[@]}"; do objects+=("$out/obj/$(echo "$src" | tr / _).o"); done
g++ "${flags[@]}" "${objects[@]}" -lceres -lglog -lpcl_common -lpcl_io -lgtest -lgtest_main -pthread \
  -o "$out/test_core_sanitized"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  "$out/test_core_sanitized" --gtest_brief=1 | tail -n 3
echo "PASSED core tests under AddressSanitizer + UndefinedBehaviorSanitizer"

#!/usr/bin/env bash
# The install space works on its own: `catkin_make install` of the built workspace (nothing is compiled
# again: test.sh has built it), then only install/setup.bash sourced, in an environment without the
# workspace's devel space: roslaunch aloam_nodelet aloam.launch (with crop_box:=true, so the installed
# config and pcl_ros's CropBox are used too) must answer the sweeps of a bag written by the installed
# aloam_sim and played with rosbag play, and the installed Python tool must run. No installed file may
# name the build or devel space or the source tree (compiled Python caches aside: they only record the
# file they were compiled from), and the package must also configure with testing off.
# Usage: check_install_space.sh OUT_DIR   (ALOAM_WS: the built workspace; default .catkin_ws)
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
ws="${ALOAM_WS:-$root/.catkin_ws}"
out="$1"
install="$ws/install"
clean_env=(env -i HOME="$HOME" PATH=/usr/bin:/bin:/usr/sbin:/sbin LANG=C.UTF-8 ROS_HOME="$out/ros_home")
[ -f "$ws/build/CMakeCache.txt" ] || { echo "FAIL: no built workspace in $ws (run scripts/build.sh first)"; exit 1; }
rm -rf "$out" "$install"
mkdir -p "$out/testing_off"
# The README's install line turns testing off: the package must configure that way too (in a build tree of
# its own, so the workspace is left as it is).
if ! "${clean_env[@]}" bash -c "cd '$out/testing_off' && cmake '$ws/src' -DCATKIN_ENABLE_TESTING=OFF \
      -DCATKIN_DEVEL_PREFIX='$out/testing_off/devel' -DCMAKE_INSTALL_PREFIX='$out/testing_off/install'" \
      >"$out/testing_off.log" 2>&1; then
  tail -30 "$out/testing_off.log"
  echo "FAIL: the package does not configure with CATKIN_ENABLE_TESTING=OFF"
  exit 1
fi
echo "install space: catkin_make install in $ws (log: $out/install_build.log)"
# Configured again in the clean environment: configured with its own devel space sourced (as `catkin_make
# run_tests` is in test.sh), catkin chains that devel space into the install space's setup.
if ! "${clean_env[@]}" bash -c "cd '$ws' && catkin_make install --force-cmake -j$(nproc)" >"$out/install_build.log" 2>&1; then
  tail -30 "$out/install_build.log"
  echo "FAIL: catkin_make install"
  exit 1
fi
# Every path into the repository, the build or the devel space that an installed file names (the install
# space's own paths aside).
path="[^\"' ;:]*"
leaks=$(grep -rIo --exclude-dir=__pycache__ -e "$root/$path" -e "$ws/devel$path" -e "$ws/build$path" "$install" |
  grep -v ":$install" || true)
if [ -n "$leaks" ]; then
  echo "$leaks" | head -20
  echo "FAIL: these installed files name the build or devel space or the source tree"
  exit 1
fi
for f in share/aloam_nodelet/launch/aloam.launch share/aloam_nodelet/launch/crop_box.launch \
         share/aloam_nodelet/config/HDL64.yaml share/aloam_nodelet/config/crop_box.yaml \
         share/aloam_nodelet/cfg/LaserMapping.cfg share/aloam_nodelet/rviz/aloam.rviz \
         share/aloam_nodelet/nodelet_plugins.xml lib/aloam_nodelet/aloam_sim lib/aloam_nodelet/demo_report.py; do
  [ -e "$install/$f" ] || { echo "FAIL: install/$f is missing"; exit 1; }
done

# The master is started here, not by roslaunch: roslaunch gives a master it starts 10 s to answer.
source "$root/test/tools/ros_master.sh"
start_ros_master "$out/rosmaster.log" "${clean_env[@]}" || exit 1
trap stop_ros_master EXIT
cat >"$out/run.sh" <<RUN
set -eo pipefail
source "$install/setup.bash"
export ROS_MASTER_URI=http://127.0.0.1:$ROS_MASTER_PORT ROS_HOSTNAME=127.0.0.1
cd "$out"
[ "\$(rospack find aloam_nodelet)" = "$install/share/aloam_nodelet" ] || { echo "FAIL: rospack finds \$(rospack find aloam_nodelet)"; exit 1; }
rosrun aloam_nodelet demo_report.py --help >/dev/null
rosrun aloam_nodelet aloam_sim --sensor VLP16 --scene urban --trajectory car --duration 4 --seed 2 --bag sim.bag >sim.log 2>&1
roslaunch aloam_nodelet aloam.launch rviz:=false crop_box:=true >pipeline.log 2>&1 &
launch=\$!
echo=
trap 'kill -INT \$launch \$echo 2>/dev/null; wait' EXIT
# Up when mapping offers its services and the manager (where scan registration runs) takes the cropped cloud.
ready=false
for i in \$(seq 90); do
  kill -0 \$launch 2>/dev/null || { tail -n 30 pipeline.log; echo "FAIL: roslaunch exited"; exit 1; }
  if rosservice list 2>/dev/null | grep -q '^/laser_mapping/save_trajectory\$' &&
     rostopic info /velodyne_points_cropped 2>/dev/null | sed -n '/^Subscribers:/,\$p' | grep -q '/aloam_manager'; then
    ready=true
    break
  fi
  sleep 1
done
\$ready || { echo "FAIL: aloam.launch was not up after 90 tries"; exit 1; }
rostopic echo -p /aft_mapped_to_init/header/stamp >answers.csv 2>/dev/null &
echo=\$!
sleep 2
rosbag play -q -d 1 --topics velodyne_points -- sim.bag
sleep 3
RUN
echo "install space: sourcing only install/setup.bash, master on port $ROS_MASTER_PORT"
status=0
"${clean_env[@]}" bash "$out/run.sh" || status=$?
answers=$(awk 'NR > 1 && NF' "$out/answers.csv" 2>/dev/null | wc -l)
expected=40
if [ $status -ne 0 ]; then
  echo "FAIL: the installed pipeline run failed (status $status); see $out/pipeline.log"
  exit 1
fi
if [ "$answers" -lt $((expected * 8 / 10)) ]; then
  tail -20 "$out/pipeline.log"
  echo "FAIL: $answers of $expected sweeps answered on aft_mapped_to_init from the install space"
  exit 1
fi
echo "PASSED install space: $answers of $expected sweeps answered by aloam.launch crop_box:=true from install/setup.bash alone"

#!/usr/bin/env bash
# The install space works on its own: `catkin_make install` into a temporary workspace, build/ and devel/
# removed, then only install/setup.bash sourced (in an environment without this repository's workspace):
# roslaunch aloam_nodelet aloam.launch (with crop_box:=true, so the installed config and pcl_ros's
# CropBox are used too) must answer the sweeps of a bag written by the installed aloam_sim and played
# with rosbag play, and the installed Python tool must run.
# Usage: check_install_space.sh OUT_DIR   (ALOAM_INSTALL_REUSE=1: keep an install space built there before)
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
out="$1"
clean_env=(env -i HOME="$HOME" PATH=/usr/bin:/bin:/usr/sbin:/sbin LANG=C.UTF-8 ROS_HOME="$out/ros_home")
if [ "${ALOAM_INSTALL_REUSE:-0}" != 1 ] || [ ! -e "$out/ws/install/setup.bash" ]; then
  rm -rf "$out"
  mkdir -p "$out/ws/src"
  ln -s "$root" "$out/ws/src/aloam_nodelet"
  echo "install space: catkin_make install in $out/ws (log: $out/install_build.log)"
  if ! "${clean_env[@]}" bash -c "cd '$out/ws' && catkin_make install -DCMAKE_BUILD_TYPE=Release \
        -DCATKIN_ENABLE_TESTING=OFF -j$(nproc)" >"$out/install_build.log" 2>&1; then
    tail -30 "$out/install_build.log"
    echo "FAIL: catkin_make install"
    exit 1
  fi
  rm -rf "$out/ws/build" "$out/ws/devel"
fi
for f in share/aloam_nodelet/launch/aloam.launch share/aloam_nodelet/launch/crop_box.launch \
         share/aloam_nodelet/config/HDL64.yaml share/aloam_nodelet/config/crop_box.yaml \
         share/aloam_nodelet/cfg/LaserMapping.cfg share/aloam_nodelet/rviz/aloam.rviz \
         share/aloam_nodelet/nodelet_plugins.xml lib/aloam_nodelet/aloam_sim lib/aloam_nodelet/demo_report.py; do
  [ -e "$out/ws/install/$f" ] || { echo "FAIL: install/$f is missing"; exit 1; }
done

port=$(/usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
cat >"$out/run.sh" <<RUN
set -eo pipefail
source "$out/ws/install/setup.bash"
export ROS_MASTER_URI=http://127.0.0.1:$port ROS_HOSTNAME=127.0.0.1
cd "$out"
[ "\$(rospack find aloam_nodelet)" = "$out/ws/install/share/aloam_nodelet" ] || { echo "FAIL: rospack finds \$(rospack find aloam_nodelet)"; exit 1; }
rosrun aloam_nodelet demo_report.py --help >/dev/null
rosrun aloam_nodelet aloam_sim --sensor VLP16 --scene urban --trajectory car --duration 4 --seed 2 --bag sim.bag >sim.log 2>&1
# roslaunch starts the master of ROS_MASTER_URI itself.
roslaunch aloam_nodelet aloam.launch rviz:=false crop_box:=true >pipeline.log 2>&1 &
launch=\$!
echo=
trap 'kill -INT \$launch \$echo 2>/dev/null; wait' EXIT
for i in \$(seq 90); do
  kill -0 \$launch || { echo "FAIL: roslaunch exited"; exit 1; }
  rosservice list 2>/dev/null | grep -q '^/laser_mapping/save_trajectory\$' && \
    rostopic info /velodyne_points_cropped 2>/dev/null | grep -q '/scan_registration' && break
  sleep 1
done
rostopic echo -p /aft_mapped_to_init/header/stamp >answers.csv 2>/dev/null &
echo=\$!
sleep 2
rosbag play -q -d 1 --topics velodyne_points -- sim.bag
sleep 3
RUN
echo "install space: sourcing only install/setup.bash, master on port $port"
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

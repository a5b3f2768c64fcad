#!/usr/bin/env bash
# Speed and memory of the core (aloam_bench, offline), then the live latency of the nodelet pipeline:
# KITTI sweeps published at 10 Hz into `roslaunch aloam_nodelet aloam.launch sensor:=HDL64`.
#   ./scripts/bench.sh                 everything (about 3 minutes)
#   ./scripts/bench.sh --live-only     the live run only
#   ./scripts/bench.sh ARGS...         ARGS go to the offline aloam_bench (e.g. --only sim --sim-sweeps 50)
set -euo pipefail
source "$(dirname "$0")/common.sh"

aloam_install_deps
aloam_build
aloam_source_ws
bin="$ALOAM_WS/devel/lib/aloam_nodelet"
kitti="$ALOAM_DATA/kitti00_101"

if [ "${1:-}" != "--live-only" ]; then
  "$bin/aloam_bench" --kitti "$kitti" "$@"
fi

if [ ! -d "$kitti/velodyne" ]; then
  aloam_log "live benchmark skipped: no KITTI sequence at $kitti"
  exit 0
fi
# A master of our own on a free port, so that a running ROS system is not disturbed.
port=$((20000 + RANDOM % 20000))
export ROS_MASTER_URI="http://localhost:$port"
aloam_log "live: roslaunch aloam.launch sensor:=HDL64 (master on port $port)"
roslaunch -p "$port" aloam_nodelet aloam.launch sensor:=HDL64 rviz:=false >"$ROS_LOG_DIR/bench_launch.log" 2>&1 &
launch_pid=$!
trap 'kill -INT $launch_pid 2>/dev/null; wait $launch_pid 2>/dev/null || true' EXIT
status=0
"$bin/aloam_bench" --live --kitti "$kitti" || status=$?
exit $status

#!/usr/bin/env bash
# The main job on an embedded default: installs what it needs, builds, runs the real nodelet pipeline
# (roslaunch aloam.launch) on a sequence, saves the mapped trajectory and the map through the nodelet's
# services, evaluates against ground truth, plots, and says where it all went.
#   ./scripts/demo.sh            simulates a 10 s urban drive with a VLP-16 (aloam_sim, exact ground truth)
#                                and plays the bag into the pipeline with rosbag play, in real time
#   ./scripts/demo.sh DIR        a KITTI-layout folder: DIR/velodyne/*.bin [+ times.txt, calib.txt,
#                                poses_kitti_gt.txt or poses.txt], replayed frame by frame (HDL64 preset;
#                                ALOAM_DEMO_SENSOR=PRESET for another sensor), e.g. ../shared/data/kitti00_101
#   ./scripts/demo.sh --screenshot PNG [DIR]
#                                the same with rviz on a virtual display (Xvfb), captured into PNG when 80 %
#                                of the sweeps are in (the README's picture: docs/images/rviz_drive.png)
set -euo pipefail
source "$(dirname "$0")/common.sh"

screenshot=""
if [ "${1:-}" = --screenshot ]; then
  [ -n "${2:-}" ] || { echo "demo: --screenshot needs a PNG path" >&2; exit 2; }
  screenshot="$(cd "$(dirname "$2")" && pwd)/$(basename "$2")"
  shift 2
fi
data="${1:-}"
if [ -n "$data" ] && [ ! -d "$data/velodyne" ]; then
  cat >&2 <<MSG
demo: $data is not a KITTI-layout sequence (no velodyne/ folder)
  Give a folder with velodyne/*.bin (optional times.txt, calib.txt, poses_kitti_gt.txt or poses.txt),
  e.g. ./scripts/demo.sh ../shared/data/kitti00_101, or no argument for the simulated default.
MSG
  exit 2
fi

aloam_install_deps
aloam_build
aloam_source_ws
bin="$ALOAM_WS/devel/lib/aloam_nodelet"
out="$ALOAM_ROOT/out/demo-$(date +%Y%m%d-%H%M%S)"
mkdir -p "$out"

# A master of our own on a free port, so a roscore (or another demo) already running is left alone.
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI="http://127.0.0.1:$port" ROS_HOSTNAME=127.0.0.1

pipeline_pid="" display_pid=""
stop_pipeline() {
  if [ -n "$pipeline_pid" ] && kill -0 "$pipeline_pid" 2>/dev/null; then
    kill -INT "$pipeline_pid" 2>/dev/null || true
    wait "$pipeline_pid" 2>/dev/null || true
  fi
  pipeline_pid=""
}
stop_all() {
  stop_pipeline
  [ -z "$display_pid" ] || kill "$display_pid" 2>/dev/null || true
}
trap stop_all EXIT

rviz=false
if [ -n "$screenshot" ]; then
  # A virtual display of rviz's window size (rviz/aloam.rviz) on a free display number.
  display=99
  while [ -e "/tmp/.X11-unix/X$display" ] || [ -e "/tmp/.X$display-lock" ]; do display=$((display + 1)); done
  Xvfb ":$display" -screen 0 1400x900x24 -nolisten tcp >"$out/xvfb.log" 2>&1 &
  display_pid=$!
  for _ in $(seq 50); do [ -e "/tmp/.X11-unix/X$display" ] && break; sleep 0.1; done
  export DISPLAY=":$display"
  rviz=true
fi

# take_screenshot_at SECONDS: in the background, captures the display into $screenshot after SECONDS.
take_screenshot_at() {
  [ -n "$screenshot" ] || return 0
  (sleep "$1" && import -window root "$screenshot" && aloam_log "screenshot: $screenshot") &
}

# start_pipeline SENSOR: roslaunch aloam.launch in the background (log in $out/pipeline.log), then waits
# until laser_mapping offers its services.
start_pipeline() {
  aloam_log "starting the pipeline: roslaunch aloam_nodelet aloam.launch sensor:=$1 rviz:=$rviz (master $ROS_MASTER_URI)"
  roslaunch aloam_nodelet aloam.launch sensor:="$1" rviz:="$rviz" >"$out/pipeline.log" 2>&1 &
  pipeline_pid=$!
  local waited=0
  until rosservice list 2>/dev/null | grep -q '^/laser_mapping/save_trajectory$'; do
    kill -0 "$pipeline_pid" 2>/dev/null || { aloam_log "the pipeline exited, see $out/pipeline.log"; exit 1; }
    [ $waited -lt 60 ] || { aloam_log "the pipeline did not come up in 60 s, see $out/pipeline.log"; exit 1; }
    sleep 1
    waited=$((waited + 1))
  done
  aloam_log "pipeline up (nodelet manager + scan_registration, laser_odometry, laser_mapping)"
}

# call_service NAME YAML: rosservice call, failing unless the nodelet reports success.
call_service() {
  local answer
  answer=$(rosservice call "$1" "$2" 2>&1) || true
  echo "$answer" | grep -q "success: True" || { aloam_log "$1 failed: $answer"; exit 1; }
}

save_results() {
  aloam_log "saving the mapped trajectory and the map (laser_mapping services)"
  call_service /laser_mapping/save_trajectory "{path: '$out/trajectory_kitti.txt', format: 'kitti'}"
  call_service /laser_mapping/save_trajectory "{path: '$out/trajectory.tum', format: 'tum'}"
  call_service /laser_mapping/save_map "{path: '$out/map.pcd'}"
}

if [ -z "$data" ]; then
  sensor=VLP16
  bag="$out/sim_urban_vlp16.bag"
  aloam_log "simulating a 10 s urban drive with a $sensor (aloam_sim, seed 7)"
  "$bin/aloam_sim" --sensor "$sensor" --scene urban --trajectory car --duration 10 --seed 7 --bag "$bag" \
    | tee "$out/simulation.txt"
  start_pipeline "$sensor"
  aloam_log "playing the bag in real time (rosbag play, velodyne_points only)"
  # Our own progress (one line per 10 % of the sweeps mapped) instead of rosbag's, which redraws a status
  # line 100 times a second and scrolls hundreds of lines where the output is not a terminal.
  python3 "$ALOAM_ROOT/scripts/demo_progress.py" --bag "$bag" &
  progress_pid=$!
  take_screenshot_at 10  # the 2 s delay below and 80 % of the 10 s drive
  # -d: time for the pipeline to connect to the new publisher before the first sweep.
  rosbag play --quiet -d 2 --topics velodyne_points -- "$bag"
  sleep 2  # the last sweeps leave mapping
  kill -TERM "$progress_pid" 2>/dev/null || true
  wait "$progress_pid" 2>/dev/null || true
  save_results
  stop_pipeline
  aloam_log "evaluating against the simulator's ground truth"
  python3 "$ALOAM_ROOT/scripts/demo_report.py" --out "$out" --estimate-tum "$out/trajectory.tum" --bag "$bag" \
    --eval "$bin/aloam_eval" --segments 10,20,40,80 --title "simulated urban drive, VLP-16, live nodelet pipeline"
else
  sensor="${ALOAM_DEMO_SENSOR:-HDL64}"
  frames=$(find "$data/velodyne" -name '*.bin' | wc -l)
  start_pipeline "$sensor"
  aloam_log "replaying $frames frames of $data into the pipeline, each waiting for its mapped pose"
  take_screenshot_at $((frames * 8 / 10 * 3 / 10 + 5))  # 80 % of the frames at about 0.3 s each
  python3 "$ALOAM_ROOT/test/tools/replay_kitti.py" "$data" "$out/trajectory_kitti.txt" --timeout 30 \
    | tee "$out/replay.txt"
  call_service /laser_mapping/save_trajectory "{path: '$out/trajectory.tum', format: 'tum'}"
  call_service /laser_mapping/save_map "{path: '$out/map.pcd'}"
  stop_pipeline
  eval_args=()
  for candidate in poses_kitti_gt.txt poses.txt; do
    if [ -f "$data/$candidate" ]; then
      eval_args=(--gt "$data/$candidate")
      # poses_kitti_gt.txt holds KITTI's camera-0 poses; poses.txt (aloam_sim) lidar poses.
      [ "$candidate" = poses_kitti_gt.txt ] && [ -f "$data/calib.txt" ] && eval_args+=(--calib "$data/calib.txt")
      # The official KITTI 00 ground truth disagrees with the scans over frames 0-5.
      [ "$candidate" = poses_kitti_gt.txt ] && eval_args+=(--start 6)
      break
    fi
  done
  [ ${#eval_args[@]} -gt 0 ] && aloam_log "evaluating against ${eval_args[1]}" ||
    aloam_log "no ground truth in $data: plotting the trajectory only"
  python3 "$ALOAM_ROOT/scripts/demo_report.py" --out "$out" --estimate-kitti "$out/trajectory_kitti.txt" \
    "${eval_args[@]}" --eval "$bin/aloam_eval" --segments 10,20,30,40,50,60,70 --frames-in "$frames" \
    --title "$(basename "$data"), $sensor, live nodelet pipeline"
fi

cat <<MSG

Results in $out
  trajectory_kitti.txt   mapped lidar poses (KITTI 3x4 rows, relative to the first mapped frame)
  trajectory.tum         the same with stamps (TUM: stamp x y z qx qy qz qw)
  map.pcd                the feature map (view with pcl_viewer)
  trajectory.png         top view of the estimate over the ground truth, error over distance travelled
  summary.txt            accuracy (aloam_eval), frames, path length
  pipeline.log           output of roslaunch and the nodelets
MSG

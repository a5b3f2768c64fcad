#!/usr/bin/env bash
# The main job on an embedded default: installs what it needs, builds, maps a KITTI-layout sequence
# with aloam_offline, evaluates it against ground truth when there is one, and says where it all went.
#   ./scripts/demo.sh            KITTI 00 frames 0-100 from ../shared/data/kitti00_101
#   ./scripts/demo.sh DIR        any KITTI-layout folder: DIR/velodyne/*.bin [+ times.txt, calib.txt,
#                                poses_kitti_gt.txt or poses.txt]
set -euo pipefail
source "$(dirname "$0")/common.sh"

data="${1:-$ALOAM_DATA/kitti00_101}"
if [ ! -d "$data/velodyne" ]; then
  cat >&2 <<MSG
demo: no KITTI-layout sequence at $data
  The default demo reads KITTI odometry sequence 00, frames 0-100, from ../shared/data/kitti00_101
  (a folder beside this repository: velodyne/*.bin, times.txt, calib.txt, poses_kitti_gt.txt).
  Give another KITTI-layout folder as the argument: ./scripts/demo.sh /path/to/sequence
MSG
  exit 2
fi

aloam_install_deps
aloam_build
bin="$ALOAM_WS/devel/lib/aloam_nodelet"
out="$ALOAM_ROOT/out/demo-$(date +%Y%m%d-%H%M%S)"
mkdir -p "$out"

aloam_log "mapping $data"
"$bin/aloam_offline" --kitti "$data" --sensor HDL64 --trajectory "$out/trajectory_kitti.txt" \
  --tum "$out/trajectory.tum" --map "$out/map.pcd" | tee "$out/summary.txt"

gt=""
for candidate in poses_kitti_gt.txt poses.txt; do
  [ -f "$data/$candidate" ] && { gt="$data/$candidate"; break; }
done
if [ -n "$gt" ]; then
  aloam_log "evaluating against $gt"
  calib=()
  [ -f "$data/calib.txt" ] && calib=(--calib "$data/calib.txt")
  start=0
  # The official KITTI 00 ground truth disagrees with the scans over frames 0-5.
  [ "$(basename "$gt")" = poses_kitti_gt.txt ] && start=6
  "$bin/aloam_eval" --gt "$gt" "${calib[@]}" --trajectory "$out/trajectory_kitti.txt" --start "$start" \
    --segments 10,20,30,40,50,60,70 | tee -a "$out/summary.txt"
else
  aloam_log "no ground truth in $data: trajectory not evaluated"
fi

cat <<MSG

Results in $out
  trajectory_kitti.txt  mapped lidar poses, KITTI 3x4 rows, relative to the first frame
  trajectory.tum        the same in TUM format
  map.pcd               the feature map (view with pcl_viewer)
  summary.txt           timings and accuracy
MSG

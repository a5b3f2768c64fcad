#!/usr/bin/env bash
# The three nodelets in one process under ThreadSanitizer: builds this package a second time with
# -fsanitize=thread in a workspace of its own (only the nodelet library, the libraries it needs and the host
# tsan_nodelet_pipeline.cpp), starts a ROS master on a free port, runs the host (a played drive with
# reconfigure and service calls during it, then unloading with sweeps in flight) and stops the master.
# Usage: run_tsan_nodelet_pipeline.sh OUT_DIR [SWEEPS | --build-only]. Exit 0: the host's checks passed and
# ThreadSanitizer reported nothing (with --build-only: it built); 1: otherwise.
set -euo pipefail
out="$(mkdir -p "$1" && cd "$1" && pwd)"
sweeps="${2:-40}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
source "$root/test/sanitize/sanitize_common.sh"
ws="$out/ws"
mkdir -p "$ws/src" "$out/run" "$out/ros_home/log"
ln -sfn "$root" "$ws/src/aloam_nodelet"

# A clean environment: no other workspace (the normal build's, a user's) may be chained into this one, or
# pluginlib could find an uninstrumented libaloam_nodelets.so first. Debian's ROS needs no setup file.
clean_env=(env -i "PATH=/usr/bin:/bin:/usr/sbin:/sbin" "HOME=${HOME:-/root}" "LANG=C.UTF-8"
           "ROS_HOME=$out/ros_home" "ROS_LOG_DIR=$out/ros_home/log")

start=$SECONDS
# -O1 as the core run: fast enough, and stacks stay readable. No -Werror: GCC's -Wtsan notes on the
# fences of third-party headers are no fault of this project (the normal build checks warnings).
# -fvisibility-inlines-hidden: our instrumented copies of boost's and roscpp's inline members (shared_ptr's
# reference counting above all) stay inside our binaries. Exported, they would take the place of the
# uninstrumented libraries' own copies for some calls only, and TSan would see half of roscpp's and
# nodelet's reference counting (a free on a worker thread against a count dropped by the unloading thread).
flags="-fsanitize=thread -fno-omit-frame-pointer -g1 -O1 -fvisibility-inlines-hidden"
(cd "$ws" && "${clean_env[@]}" catkin_make -DCMAKE_BUILD_TYPE=None "-DCMAKE_CXX_FLAGS=$flags" \
  "-DCMAKE_SHARED_LINKER_FLAGS=-fsanitize=thread" "-DCMAKE_EXE_LINKER_FLAGS=-fsanitize=thread" \
  -DCATKIN_ENABLE_TESTING=OFF -DALOAM_TSAN_HOST=ON tsan_nodelet_pipeline -j"$(nproc)") >"$out/build.log" 2>&1 ||
  { tail -n 40 "$out/build.log"; echo "FAILED building the nodelets with ThreadSanitizer (see $out/build.log)"; exit 1; }
echo "built the nodelets and the host with ThreadSanitizer in $((SECONDS - start)) s"
host="$ws/devel/lib/aloam_nodelet/tsan_nodelet_pipeline"
[ "$sweeps" != --build-only ] || exit 0

source "$root/test/tools/ros_master.sh"
start_ros_master "$out/rosmaster.log" "${clean_env[@]}" || exit 1
trap stop_ros_master EXIT
export_env=("${clean_env[@]}" "ROS_MASTER_URI=http://127.0.0.1:$ROS_MASTER_PORT" "ROS_IP=127.0.0.1")

log="$out/host.log"
start=$SECONDS
status=0
"${export_env[@]}" "TSAN_OPTIONS=$(tsan_options "$root")" bash -c '
  source "$1/devel/setup.bash" && exec timeout --kill-after=30 1800 "$2" "$3" "$4"' _ "$ws" "$host" "$out/run" "$sweeps" \
  >"$log" 2>&1 || status=$?
# (The host runs in the same clean environment, with only this workspace sourced.)
grep -E '^(ok|FAILED|PASSED|nodelet library|unloaded)' "$log" || true
# How often each suppression matched (third-party reports hidden), for the record.
sed -n '/^ThreadSanitizer: Matched/,/^$/p' "$log" | head -n 30
echo "ran the nodelet pipeline under ThreadSanitizer in $((SECONDS - start)) s (log: $log)"
failed=0
grep -q "^nodelet library: $ws/devel/lib/libaloam_nodelets.so" "$log" ||
  { echo "the host did not load the instrumented nodelet library from $ws"; failed=1; }
reports=$(tsan_reports "$log")
[ "$reports" -eq 0 ] || failed=1
if [ "$status" -ne 0 ] || [ "$failed" -ne 0 ]; then
  echo "FAILED the nodelet pipeline under ThreadSanitizer: exit $status, $reports reports (see $log)"
  exit 1
fi
echo "PASSED the nodelet pipeline under ThreadSanitizer (no report)"

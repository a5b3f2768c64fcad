#!/usr/bin/env bash
# Long run for test.sh: 18,000 simulated VLP-16 sweeps (30 minutes of data at 10 Hz, 18 km at 10 m/s)
# through the core pipeline (no ROS: the nodelets on this 2-core machine would need more than CI's time),
# as fast as it runs; resident memory and map size printed every 1000 sweeps, and the run fails unless they
# flatten (see test/longrun/long_drive_memory.cpp). To fit CI (about 7 minutes here under load), every
# second firing is simulated (0.4 deg azimuth steps), odometry and mapping solve with 3 iterations and one
# correspondence search, and map cubes are 25 m (a smaller submap): none of this changes what is allocated
# per sweep or how the map evicts. The same run with every default: --column-step 1 --solver-budget 0
# --cube-size 50.
# Usage: run_long_drive.sh BIN_DIR OUT_DIR [SWEEPS]. Exit 0: passed; 1: failed.
set -euo pipefail
bin="$1"
out="$2"
sweeps="${3:-18000}"
mkdir -p "$out"
start=$(date +%s)
status=0
"$bin/aloam_long_drive" --sweeps "$sweeps" --report-every 1000 --column-step 2 --solver-budget 3 --cube-size 25 \
  | tee "$out/long_drive.txt" || status=$?
echo "long drive: $(($(date +%s) - start)) s (report in $out/long_drive.txt)"
exit $status

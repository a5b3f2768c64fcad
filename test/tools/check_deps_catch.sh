#!/usr/bin/env bash
# The dependency self-check catches a missing package: for each package below, the check runs on a copy of
# ALOAM_DEBIAN_PACKAGES without it and must fail, naming what that package provides. (A package that the
# rest of the list pulls in anyway is reported and passed over: leaving it out changes nothing.)
# These are the packages a fresh machine once lacked, one of each kind the check covers: Python modules
# of the test nodes, a command of the tests and the README, a nodelet of a launch file, a CMake package, a
# tool of test.sh.
set -uo pipefail
source "$(dirname "$0")/../../scripts/common.sh"

declare -A expect=(
  [python3-std-srvs]="python module std_srvs"
  [python3-diagnostic-msgs]="python module diagnostic_msgs"
  [rosbash]="command rosrun"
  [libpcl-ros-dev]="pcl/CropBox"
  [libceres-dev]="find_package(Ceres)"
  [clang-format]="command clang-format"
)
tested=0 failed=0
for pkg in "${!expect[@]}"; do
  rest=()
  for p in "${ALOAM_DEBIAN_PACKAGES[@]}"; do [ "$p" = "$pkg" ] || rest+=("$p"); done
  if /usr/bin/python3 "$ALOAM_ROOT/scripts/check_deps.py" --provided "$pkg" "${rest[@]}"; then
    echo "check_deps_catch: $pkg is pulled in by the rest of the list; leaving it out changes nothing"
    continue
  fi
  tested=$((tested + 1))
  out=$(ALOAM_DEPS_OMIT="$pkg" aloam_check_deps 2>&1)
  status=$?
  if [ $status -eq 0 ]; then
    echo "check_deps_catch: FAILED: without $pkg the self-check still passes"
    failed=$((failed + 1))
  elif ! grep -qF "${expect[$pkg]}" <<<"$out"; then
    echo "check_deps_catch: FAILED: without $pkg the self-check fails but does not name ${expect[$pkg]}:"
    echo "$out"
    failed=$((failed + 1))
  else
    echo "check_deps_catch: without $pkg: $(grep -F "${expect[$pkg]}" <<<"$out" | head -1)"
  fi
done
echo "check_deps_catch: $tested packages left out, $failed not caught"
[ $tested -ge 4 ] && [ $failed -eq 0 ]

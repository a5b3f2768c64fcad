# Sourced (not run) by run_sanitized_core_tests.sh (AddressSanitizer + UBSan) and run_tsan_core_tests.sh
# (ThreadSanitizer): both build the ROS-free core and its gtest suite outside catkin (the core needs no ROS)
# the same way and differ only in the sanitizer flags and in how they judge the run. The two ThreadSanitizer
# checks (those core tests and run_tsan_nodelet_pipeline.sh) share its options and its report count.

# tsan_options ROOT: every report is printed (halt_on_error=0) and makes the process exit 66 at the end;
# second_deadlock_stack: lock-order reports show both acquisitions; the documented suppressions.
tsan_options() {
  echo "halt_on_error=0 exitcode=66 second_deadlock_stack=1 history_size=7 print_suppressions=1" \
    "suppressions=$1/test/sanitize/tsan.supp"
}

# tsan_reports LOG: prints how many reports LOG holds (the log is searched as well as the exit code read,
# since a process that exits on its own path could hide the code); their summaries, counted, go to stderr.
tsan_reports() {
  local reports
  reports=$(grep -c '^WARNING: ThreadSanitizer' "$1" || true)
  if [ "$reports" -ne 0 ]; then
    grep '^SUMMARY: ThreadSanitizer' "$1" | sort | uniq -c >&2 || true
  fi
  echo "$reports"
}

# Not in the sanitized suite: test_kitti_accuracy (real data through the dataset reader, a single-threaded
# accuracy check that takes minutes without a sanitizer) and test_param_defaults (reads the source tree's
# files; no threads, no memory of its own worth checking). Every other test is globbed, so a new core test
# or source is checked without editing the scripts.
# The gtest filter of both runs: everything but the long loop-closure drives, which run the code of the short
# loop-closure tests (the session test among them) over hundreds of frames and take minutes under a sanitizer.
sanitize_gtest_filter() {
  echo "-LoopClosureTest.ClosesADriftedOutAndBackDriveWithTheTrueRelativePose:LoopClosureTest.LookAlikeBlocksNeverClose:LoopClosurePipelineTest.*:LoopClosureTwoSessionsTest.*"
}

# The suites that start no thread (the simulator, the map's containers, the metrics): ThreadSanitizer cannot
# find anything there (AddressSanitizer runs them), so its filter leaves them out and its build leaves out
# the test files that hold nothing else (sanitize_core_sources). Globs, as gtest's filter and bash read them.
TSAN_NO_THREAD_SUITES=('Sim*' Scenes Trajectories GroundProfile CubeMapTest KdTree KittiMetrics TrajectoryIo
  LongDriveTest SensorModelTest StampCheck)

# ThreadSanitizer's filter leaves out more: those suites, and the longest accuracy and state drives of
# mapping, localization and remapping, whose threads the shorter drives of their suites run the same way
# (ShortDriveTracksWithinFiveCentimetres, HardFrameGetsMoreSearches, GlobalLocalizationFindsThePose,
# LostInUnmappedSpaceRecoversOnItsOwn, PipelinesShareNoState stay).
tsan_gtest_filter() {
  local no_threads suite
  for suite in "${TSAN_NO_THREAD_SUITES[@]}"; do no_threads+=":$suite.*"; done
  local drives="LaserMappingTest.ReusedSearchesGiveTheTrajectoryOfFreshOnes"
  drives+=":LaserMappingTest.EvictionBoundsTheMapOverLongDrive:LaserMappingTest.FirstSweepEntersTheMapDeskewedLate"
  drives+=":LaserMappingTest.EdgeLinesAlongTheRingsDoNotPitchTheFlatDrive:LaserMappingTest.LaneChangeDriveStaysBounded"
  drives+=":LocalizerTest.JumpBackStartsOver:LocalizerTest.ConvergesFromOneMetreAndTenDegreesOnAnotherDrive"
  drives+=":LocalizerTest.OdometryRestartCarriesTheLastPoseOver:LocalizerTest.InitialPoseResetsAtAnyTime"
  drives+=":PipelineInputsTest.CorridorRemappingKeepsOnlyTheWeakDirection"
  echo "$(sanitize_gtest_filter)$no_threads:$drives"
}

# only_threadless_suites FILE: true if every gtest suite FILE defines is in TSAN_NO_THREAD_SUITES.
only_threadless_suites() {
  local suite pattern found
  for suite in $(grep -oE '^TEST(_F|_P)?\( *[A-Za-z0-9_]+' "$1" | sed -E 's/.*\( *//' | sort -u); do
    found=false
    for pattern in "${TSAN_NO_THREAD_SUITES[@]}"; do
      # shellcheck disable=SC2053
      if [[ $suite == $pattern ]]; then found=true; fi
    done
    $found || return 1
  done
}

# sanitize_run_sharded LOG COMMAND...: runs a gtest binary as 4 shards per core, one per core at a time
# (gtest's GTEST_TOTAL_SHARDS and GTEST_SHARD_INDEX: each test runs in exactly one shard). It helps where a
# sanitized test keeps about one core busy (ASan); ThreadSanitizer's tests already keep ~1.4 busy and gain
# little from it (docs/development.md).
# LOG then holds every shard's output. Returns 0 only if every shard exited 0.
sanitize_run_sharded() {
  local log="$1" shards i status=0
  shift
  shards=$((4 * $(nproc)))
  seq 0 $((shards - 1)) |
    xargs -P "$(nproc)" -I '{}' env GTEST_TOTAL_SHARDS=$shards GTEST_SHARD_INDEX='{}' \
      bash -c '"$@" >"$0.{}" 2>&1 || exit 1' "$log" "$@" || status=1
  for i in $(seq 0 $((shards - 1))); do cat "$log.$i"; done >"$log"
  rm -f "$log".*
  return "$status"
}

# sanitize_core_sources ROOT SET: sources, one a line. SET: `core` (the core library alone, which the
# fuzzers link too), `tests` (the simulator, the metrics and the test files of the sanitized core tests),
# `tsan_tests` (those without the test files that only hold suites ThreadSanitizer leaves out).
sanitize_core_sources() {
  local root="$1" set="$2" src name
  shopt -s nullglob
  if [ "$set" = core ]; then
    printf '%s\n' "$root"/src/core/*.cpp
    return
  fi
  printf '%s\n' "$root"/src/sim/*.cpp "$root"/src/eval/*.cpp
  for src in "$root"/test/core/test_*.cpp; do
    name="$(basename "$src")"
    [[ "$name" == test_kitti_accuracy.cpp || "$name" == test_param_defaults.cpp ]] && continue
    [ "$set" = tsan_tests ] && only_threadless_suites "$src" && continue
    echo "$src"
  done
}

# sanitize_stale ROOT OUT INPUTS...: true if OUT is missing or older than one of INPUTS or than any header of
# the project. The one rule by which the sanitized and fuzz builds reuse what they built before.
sanitize_stale() {
  local root="$1" out="$2" input
  shift 2
  [ -e "$out" ] || return 0
  for input in "$@"; do
    if [ -e "$input" ] && [ "$input" -nt "$out" ]; then return 0; fi
  done
  [ -n "$(find "$root/include" "$root/src" "$root/test" -name '*.h' -newer "$out" -print -quit)" ]
}

# sanitize_command ROOT COMPILER SANITIZER_FLAGS...: the compile command of a sanitized build, one word a
# line (mapfile -t): the optimisation, debug and include flags every such build shares around its own.
sanitize_command() {
  local root="$1" compiler="$2"
  shift 2
  printf '%s\n' "$compiler" -std=c++17 -O1 -g1 -fno-omit-frame-pointer "$@" -I "$root/include" \
    -isystem /usr/include/eigen3 -isystem /usr/include/pcl-1.13
}

# sanitize_objects OBJ_DIR ROOT SOURCES...: the objects of SOURCES, one a line, named after their paths in
# the project.
sanitize_objects() {
  local dir="$1" root="$2" src rel
  shift 2
  for src in "$@"; do rel="${src#"$root"/}"; echo "$dir/${rel//\//_}.o"; done
}

# sanitize_compile ROOT OBJ_DIR COMPILER FLAGS... -- SOURCES...: compiles the stale SOURCES into OBJ_DIR on
# every core (sanitize_objects names them). New flags or another compiler empty OBJ_DIR first. An object is
# written under a temporary name and renamed, so a reader never links a half-written one. Returns non-zero
# if a compile fails; every step is checked here (callers may run it under `||`, where `set -e` does not
# apply).
sanitize_compile() {
  local root="$1" dir="$2" flags=() src obj stale=()
  shift 2
  while [ $# -gt 0 ] && [ "$1" != -- ]; do flags+=("$1"); shift; done
  [ $# -gt 0 ] || { echo "sanitize_compile: no -- before the sources"; return 1; }
  shift
  mkdir -p "$dir" || return 1
  if [ "$(cat "$dir/.flags" 2>/dev/null)" != "${flags[*]}" ]; then
    rm -f "$dir"/*.o
    printf '%s' "${flags[*]}" >"$dir/.flags" || return 1
  fi
  for src in "$@"; do
    obj="$(sanitize_objects "$dir" "$root" "$src")"
    if sanitize_stale "$root" "$obj" "$src"; then stale+=("$src" "$obj"); fi
  done
  [ ${#stale[@]} -gt 0 ] || return 0
  # xargs hands each job a source and its object after the compiler and flags.
  printf '%s\n' "${stale[@]}" | xargs -r -d '\n' -n 2 -P "$(nproc)" bash -c '
    src="${*: -2:1}" obj="${*: -1}"
    "${@:1:$#-2}" -c "$src" -o "$obj.tmp$$" && mv "$obj.tmp$$" "$obj"' _ "${flags[@]}" ||
    { echo "FAILED compiling with ${flags[*]}"; return 1; }
}

# sanitize_build_core_tests ROOT OUT_DIR EXE SET COMMAND...: compiles the core into OUT_DIR/core and the
# SET of test sources (sanitize_core_sources) into OUT_DIR/obj with COMMAND (sanitize_command), and links
# OUT_DIR/EXE if an object is newer. Returns non-zero if anything fails to build.
sanitize_build_core_tests() {
  local root="$1" out="$2" exe="$3" set="$4"
  shift 4
  local start=$SECONDS core=() tests=() objects=()
  mapfile -t core < <(sanitize_core_sources "$root" core)
  mapfile -t tests < <(sanitize_core_sources "$root" "$set")
  sanitize_compile "$root" "$out/core" "$@" -- "${core[@]}" || return 1
  sanitize_compile "$root" "$out/obj" "$@" -- "${tests[@]}" || return 1
  # Only the objects of today's sources (an old object of a removed source may still be there).
  mapfile -t objects < <(sanitize_objects "$out/core" "$root" "${core[@]}"
    sanitize_objects "$out/obj" "$root" "${tests[@]}")
  if sanitize_stale "$root" "$out/$exe" "${objects[@]}"; then
    "$@" "${objects[@]}" -lceres -lglog -lpcl_common -lpcl_io -lgtest -lgtest_main -pthread -o "$out/$exe" ||
      { echo "FAILED linking the core tests with $*"; return 1; }
  fi
  echo "built the core tests with $* in $((SECONDS - start)) s"
}

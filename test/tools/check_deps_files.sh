#!/usr/bin/env bash
# The dependency self-check reads the project's sources only, and a file it cannot read fails it with a
# message instead of crashing it. On a user's machine Python writes bytecode beside the rostest helpers
# (test/rostest/__pycache__/*.cpython-311.pyc), which the check once took for C sources and crashed on.
# Each case runs scripts/check_deps.py on a copy of the project, both as a git work tree and as a plain
# folder (a tarball): with stray bytecode and binary files it must pass; with a source that is not UTF-8, or
# one that the check cannot parse, it must fail and say why.
set -uo pipefail
source "$(dirname "$0")/../../scripts/common.sh"

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failed=0

# copy_project DIR [git]: the project's files (no build tree, no history) in DIR, a git work tree if asked.
copy_project() {
  mkdir -p "$1"
  tar -C "$ALOAM_ROOT" --exclude=./.git --exclude=./.catkin_ws --exclude=./out --exclude='__pycache__' \
    --exclude='*.pyc' -cf - . | tar -C "$1" -xf -
  if [ "${2:-}" = git ]; then
    git -C "$1" init -q && git -C "$1" add -A
  fi
}

# expect NAME STATUS PATTERN DIR: the check on DIR exits with STATUS (0 or 1) and prints PATTERN.
expect() {
  local out status=0
  out=$(/usr/bin/python3 "$ALOAM_ROOT/scripts/check_deps.py" "$4" "${ALOAM_DEBIAN_PACKAGES[@]}" 2>&1) || status=$?
  if [ "$status" -ne "$2" ] || ! grep -qF -- "$3" <<<"$out"; then
    echo "check_deps_files: FAILED: $1: exit $status (expected $2), output:"
    echo "$out" | tail -15
    failed=$((failed + 1))
  else
    echo "check_deps_files: $1: exit $status, $(grep -F -- "$3" <<<"$out" | head -1)"
  fi
}

stray_bytes=$'\xa7\x0d\x0d\x0a\x00\x00\x00\x00\xe3'
for mode in git plain; do
  tree="$work/$mode-stray"
  copy_project "$tree" "$mode"
  # Bytecode as Python writes it, and the same name outside __pycache__ (it matched the former *.[ch]* glob).
  mkdir -p "$tree/test/rostest/__pycache__"
  printf '%s' "$stray_bytes" >"$tree/test/rostest/__pycache__/aloam_rostest_utils.cpython-311.pyc"
  printf '%s' "$stray_bytes" >"$tree/test/rostest/aloam_rostest_utils.cpython-311.pyc"
  printf '%s' "$stray_bytes" >"$tree/test/core/recording.bin"
  expect "$mode tree with stray bytecode and binary files" 0 "dependency self-check passed" "$tree"

  tree="$work/$mode-latin1"
  copy_project "$tree"
  printf '// caf\xe9 au lait\nint unused_latin1 = 0;\n' >"$tree/test/core/latin1_comment.cpp"
  [ "$mode" = git ] && git -C "$tree" init -q && git -C "$tree" add -A
  expect "$mode tree with a source that is not UTF-8" 1 "test/core/latin1_comment.cpp: not UTF-8 text" "$tree"

  tree="$work/$mode-nul"
  copy_project "$tree"
  printf 'import os\x00\n' >"$tree/test/tools/nul_byte.py"
  [ "$mode" = git ] && git -C "$tree" init -q && git -C "$tree" add -A
  expect "$mode tree with a Python file the check cannot parse" 1 "dependency self-check FAILED" "$tree"
done

echo "check_deps_files: 6 cases, $failed failed"
[ $failed -eq 0 ]

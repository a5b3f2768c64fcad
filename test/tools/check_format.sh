#!/usr/bin/env bash
# Every C++ file of the repository is formatted as .clang-format says (clang-format --dry-run --Werror).
# Fix with: clang-format -i $(git ls-files '*.cpp' '*.h')
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$root"
mapfile -t files < <(git ls-files '*.cpp' '*.h' '*.hpp' 2>/dev/null || find src include test -name '*.cpp' -o -name '*.h')
[ ${#files[@]} -gt 0 ] || { echo "check_format: no C++ files found"; exit 1; }
if clang-format --dry-run --Werror "${files[@]}" 2>/tmp/aloam_format.$$; then
  echo "check_format: ${#files[@]} files formatted as .clang-format says"
  rm -f /tmp/aloam_format.$$
else
  grep -c 'error:' /tmp/aloam_format.$$ | xargs echo "check_format: FAILED, places to reformat:"
  grep 'error:' /tmp/aloam_format.$$ | cut -d: -f1 | sort | uniq -c
  rm -f /tmp/aloam_format.$$
  exit 1
fi

#!/usr/bin/env bash
# The parameter tables of README.md and docs/parameters.md are what scripts/param_tables.py generates from
# cfg/*.cfg, and the check catches a table that is not: on a copy of README.md with one default altered,
# --check must fail and name the table, and --write must restore it.
# Usage: check_param_tables.sh   (exit 0 passed, else failed)
set -euo pipefail
source "$(dirname "$0")/../../scripts/common.sh"
tables="$ALOAM_ROOT/scripts/param_tables.py"
fail() { echo "check_param_tables: FAILED: $*"; exit 1; }

/usr/bin/python3 "$tables" --check "$ALOAM_ROOT/README.md" "$ALOAM_ROOT/docs/parameters.md" \
  || fail "a table differs from cfg/ (fix: scripts/param_tables.py --write README.md docs/parameters.md)"

# Negative self-test: a copy of README.md with the default of the first row of its first table altered.
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# (awk program kept on single lines: the dependency self-check reads shell lines one by one)
find_row='BEGIN { FS = OFS = "|" } /^<!-- param-table: / { inside = 1; rows = 0; print; next } /^<!-- \/param-table -->/ { inside = 0 }'
alter='inside && /^\|/ { rows++; if (rows == 3 && !done) { $4 = " 12345.6 "; done = 1 } } { print }'
awk "$find_row $alter" "$ALOAM_ROOT/README.md" >"$tmp/README.md"
cmp -s "$ALOAM_ROOT/README.md" "$tmp/README.md" && fail "the self-test found no table row to alter"
status=0
/usr/bin/python3 "$tables" --check "$tmp/README.md" >"$tmp/check.log" 2>&1 || status=$?
cat "$tmp/check.log"
[ "$status" -eq 1 ] || fail "--check exited $status on an altered default (expected 1)"
grep -q "DIFFERS: .*README.md" "$tmp/check.log" || fail "--check did not name the altered table"
/usr/bin/python3 "$tables" --write "$tmp/README.md" >/dev/null
cmp -s "$ALOAM_ROOT/README.md" "$tmp/README.md" || fail "--write did not restore the altered table"
echo "check_param_tables: passed (tables as generated; an altered default is caught and rewritten)"

# Shared by the end-to-end check scripts in this folder. Source it.

# The value of `key: value` in FILE (as aloam_eval prints its headline figures).
figure() { awk -v k="$1:" '$1 == k {print $2}' "$2"; }

# at_most LABEL VALUE LIMIT: prints a failure and returns 1 unless VALUE is a number <= LIMIT.
at_most() {
  awk -v v="$2" -v m="$3" 'BEGIN {exit !(v != "" && v + 0 == v && v <= m)}' && return 0
  echo "FAIL: $1 $2 > $3"
  return 1
}

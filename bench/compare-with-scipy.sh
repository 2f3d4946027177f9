#!/usr/bin/env bash
# Speed and accuracy against a scipy script, side by side in one run, on the bench records.
#
#   bash bench/compare-with-scipy.sh [RECORDS...]     (default: envelope strokes multisine)
#   FRICTION_BENCH_WORK=nlr bash bench/compare-with-scipy.sh    (NLR only; LG's script fits take minutes)
#
# For each record of data/bench/ (est.csv, val.csv) it times, one after the other on one core:
#   NLR, M = 10 fixed:  friction-identify identify --model maxwell-slip --operators 10
#                       scipy_friction.py --methods nlr --M 10
#   LG:                 friction-identify identify --model lugre
#                       scipy_friction.py --methods lg
# and prints seconds, validation RSS/SSS % and the ratio scipy / friction.  The friction figure
# is the CLI's wall time (reading, identification, validation, output), scipy's the fit time it
# reports.  Needs python3-numpy and python3-scipy; ../shared/bench/scipy_friction.py.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cli="${FRICTION_CLI:-$root/build/apps/friction-identify}"
scipy="${SCIPY_FRICTION:-$root/../shared/bench/scipy_friction.py}"
records=("$@")
((${#records[@]})) || records=(envelope strokes multisine)
export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1
# Debian's python3 carries python3-scipy; a python3 earlier on PATH (pyenv, venv) may not.
python="${PYTHON:-$(command -v /usr/bin/python3 || command -v python3)}"
if ! "$python" -c 'import numpy, scipy' 2>/dev/null; then
  echo "error: $python cannot import numpy and scipy (Debian: apt-get install python3-scipy)" >&2
  exit 1
fi
if [[ ! -f "$scipy" ]]; then
  echo "error: the scipy script $scipy is missing (set SCIPY_FRICTION to its path)" >&2
  exit 1
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

ours() {  # ours RECORD ARGS... -> "seconds validation%"
  local r=$1
  shift
  local t0 t1
  t0=$(date +%s.%N)
  taskset -c 0 "$cli" identify --data "$root/data/bench/$r/est.csv" \
    --validate "$root/data/bench/$r/val.csv" --format json "$@" >"$tmp/ours.json" 2>/dev/null
  t1=$(date +%s.%N)
  python3 -c "import json,sys; d=json.load(open('$tmp/ours.json')); \
print('%.2f %.4f' % ($t1 - $t0, d['validation']['rss_sss_percent']))"
}

theirs() {  # theirs RECORD METHOD [ARGS...] -> "seconds validation%"
  local r=$1 m=$2
  shift 2
  taskset -c 0 "$python" "$scipy" --data-dir "$root/data/bench" --case "$r" --methods "$m" "$@" \
    >"$tmp/theirs.json" 2>/dev/null
  python3 -c "import json; m=json.load(open('$tmp/theirs.json'))['methods']['$m']; \
print('%.2f %.4f' % (m['fit_s'], m['val']['rss_sss_pct']))"
}

printf '%-10s %-6s %10s %10s %10s %10s %8s\n' record work "friction s" "valid. %" "scipy s" \
  "valid. %" "ratio"
for r in "${records[@]}"; do
  read -r fs fv < <(ours "$r" --model maxwell-slip --operators 10)
  read -r ss sv < <(theirs "$r" nlr --M 10)
  printf '%-10s %-6s %10s %10s %10s %10s %7.1fx\n' "$r" NLR "$fs" "$fv" "$ss" "$sv" \
    "$(python3 -c "print($ss / $fs)")"
  [[ "${FRICTION_BENCH_WORK:-nlr lg}" == *lg* ]] || continue
  read -r fs fv < <(ours "$r" --model lugre)
  read -r ss sv < <(theirs "$r" lg)
  printf '%-10s %-6s %10s %10s %10s %10s %7.1fx\n' "$r" LG "$fs" "$fv" "$ss" "$sv" \
    "$(python3 -c "print($ss / $fs)")"
done

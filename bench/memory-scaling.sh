#!/usr/bin/env bash
# Time and peak resident memory of the CLI against the record length (issue 8, item 5):
#
#   bash bench/memory-scaling.sh [SIZES...]      (default: 10000 100000 1000000)
#
# For each size N it writes an estimation and a validation record with `generate` (the GMS
# reference system, not the Maxwell Slip model that is fitted; multisine at 1 kHz, white force
# noise, a 10 nm encoder), then runs, each as its own process under /usr/bin/time:
#   identify --model maxwell-slip --operators 4      NLR with M = 4 fixed
#   validate                                         the identified model on the validation record
#   simulate                                         the same model's force on it, as CSV
#   diagnose (N <= FRICTION_BENCH_DIAGNOSE_UP_TO only, default 100000: a diagnosis of 1M samples
#             takes tens of minutes)
# and prints wall seconds, peak RSS and RSS per sample.  Targets: identify, validate and simulate
# <= 200 B/sample at 1M, diagnose <= 500.  Run it on an otherwise idle machine.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cli=${FRICTION_CLI:-$root/build/apps/friction-identify}
[[ -x "$cli" ]] || { echo "error: $cli not built (bash scripts/setup.sh)" >&2; exit 1; }
[[ -x /usr/bin/time ]] || { echo "error: /usr/bin/time is needed (Debian package time)" >&2; exit 1; }
sizes=("$@")
((${#sizes[@]})) || sizes=(10000 100000 1000000)
tmp=$(mktemp -d "${TMPDIR:-/tmp}/friction-memory.XXXXXX")
trap 'rm -rf "$tmp"' EXIT

printf '%-9s %-9s %9s %10s %10s\n' samples command seconds "peak MB" "B/sample"
measure() { # measure N LABEL COMMAND...
  local n=$1 label=$2
  shift 2
  /usr/bin/time -f '%e %M' -o "$tmp/time" "$@" >/dev/null 2>"$tmp/stderr" ||
    { cat "$tmp/stderr" >&2; echo "error: $label failed on $n samples" >&2; exit 1; }
  local seconds kb
  read -r seconds kb <"$tmp/time"
  awk -v n="$n" -v l="$label" -v s="$seconds" -v kb="$kb" \
    'BEGIN { printf "%-9s %-9s %9.2f %10.1f %10.0f\n", n, l, s, kb / 1024, kb * 1024 / n }'
}

for n in "${sizes[@]}"; do
  duration=$(awk -v n="$n" 'BEGIN { print n / 1000 }')
  for part in est val; do
    seed=$([[ $part == est ]] && echo 11 || echo 12)
    "$cli" generate --model gms --excitation multisine --duration "$duration" --rate 1000 \
      --noise 0.01 --resolution 1e-8 --seed "$seed" --out "$tmp/$part.csv" >/dev/null 2>"$tmp/stderr" ||
      { cat "$tmp/stderr" >&2; exit 1; }
  done
  measure "$n" identify "$cli" identify --model maxwell-slip --operators 4 --data "$tmp/est.csv" \
    --format json --out "$tmp/model.json"
  measure "$n" validate "$cli" validate --model-file "$tmp/model.json" --data "$tmp/val.csv" \
    --format json --out "$tmp/validation.json"
  measure "$n" simulate "$cli" simulate --model-file "$tmp/model.json" --data "$tmp/val.csv" \
    --out "$tmp/sim.csv"
  if ((n <= ${FRICTION_BENCH_DIAGNOSE_UP_TO:-100000})); then
    measure "$n" diagnose "$cli" diagnose --data "$tmp/est.csv" --validate "$tmp/val.csv" \
      --format json --out "$tmp/diagnose.json"
  fi
done

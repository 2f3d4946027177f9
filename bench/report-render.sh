#!/usr/bin/env bash
# How long the 100k-sample reports take to write and to render:  bash bench/report-render.sh
#
# Runs bench_report (Google Benchmark: building and writing the compare, diagnose and validate
# reports of two 100,000-sample records, and their sizes), keeps the files it wrote, and loads
# each in headless Chromium with scripts/check-report.py --timing: the time from navigation to the
# load event, and the time to lay out and paint the whole page; the check itself runs too.
# Not a test (the times depend on the machine); the README quotes a run.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../scripts/common.sh"
cd "$FRICTION_ROOT"

BENCH="$FRICTION_BUILD_DIR/bench/bench_report"
[[ -x "$BENCH" ]] || die "$BENCH is not built"
DIR=$(mktemp -d "${TMPDIR:-/tmp}/friction-report-bench.XXXXXX")
trap 'rm -rf "$DIR"' EXIT

say "Writing the reports (bench_report)"
FRICTION_REPORT_BENCH_DIR="$DIR" "$BENCH" --benchmark_counters_tabular=true

say "Rendering them in headless Chromium"
for f in compare diagnose validate; do
  python3 scripts/check-report.py "$DIR/$f-100k.html" --timing | tail -2
done

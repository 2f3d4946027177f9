#!/usr/bin/env bash
# The reports checked in a real browser:  bash scripts/check-reports.sh   (run by run-tests.sh)
#
#   1. writes the reports of `compare` and `diagnose` on data/ (and `validate` of the generating
#      model, data/true-model.json, on data/validation.csv) into build/report-check/;
#   2. checks each in headless Chromium with scripts/check-report.py: no console error, every
#      expected plot present, enough marks with finite coordinates inside each plot's viewBox,
#      plot areas that are not only background in the screenshot;
#   3. checks the checker: five deliberately broken copies of the validate report (a resource from
#      the network, a plot missing, a plot without marks, a plot whose marks lie outside its
#      viewBox, a plot whose marks are painted in the background colour, which only the
#      screenshot can tell) must each fail, for the reason they were broken.
#
# Needs Debian's chromium (setup.sh installs it; CHROMIUM=PATH overrides) and python3.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
cd "$FRICTION_ROOT"

CLI="$FRICTION_BUILD_DIR/apps/friction-identify"
OUT="$FRICTION_BUILD_DIR/report-check"
CHECK=(python3 scripts/check-report.py --chromium "${CHROMIUM:-chromium}")

[[ -x "$CLI" ]] || die "$CLI is not built"
command -v "${CHROMIUM:-chromium}" >/dev/null 2>&1 ||
  die "chromium is not installed (scripts/setup.sh installs Debian's chromium)"
command -v python3 >/dev/null 2>&1 || die "python3 is not installed"
rm -rf "$OUT"
mkdir -p "$OUT"

# The plots each report must have (ids as report_pages.cpp names them).
per_record() { # ROLE PREFIX...: the figures of one model on one record
  local role=$1 p
  shift
  for p in "$@"; do
    printf -- '--expect %s-time --expect %s-zoom --expect %s-loops%s --expect %s-sliding ' \
      "$role$p" "$role$p" "$role$p" "${LOOP_SUFFIX:-}" "$role$p"
  done
}

# Independent commands run side by side (a check is mostly one Python process waiting for
# Chromium, and the two cores were half idle one check at a time); each one's output goes to a
# log, shown when it fails.
PIDS=()
NAMES=()
start() { # start NAME COMMAND...: in the background, output in $OUT/NAME.log
  NAMES+=("$1")
  "${@:2}" >"$OUT/$1.log" 2>&1 &
  PIDS+=($!)
}
finish() { # waits for everything start()ed; fails if any failed, after showing its log
  local i status=0
  for i in "${!PIDS[@]}"; do
    if ! wait "${PIDS[$i]}"; then
      cat "$OUT/${NAMES[$i]}.log"
      echo "error: ${NAMES[$i]} failed (log: $OUT/${NAMES[$i]}.log)" >&2
      status=1
    fi
  done
  PIDS=()
  NAMES=()
  return "$status"
}

say "Writing the reports on data/"
start write-compare "$CLI" compare --data data/estimation.csv --validate data/validation.csv \
  --out "$OUT/compare.json" --report "$OUT/compare.html"
start write-diagnose "$CLI" diagnose --data data/estimation.csv --validate data/validation.csv \
  --format json --out "$OUT/diagnose.json" --report "$OUT/diagnose.html"
start write-validate "$CLI" validate --model-file data/true-model.json \
  --data data/validation.csv --out "$OUT/validate.txt" --report "$OUT/validate.html"
finish
findings=$(python3 -c 'import json,sys; print(len(json.load(open(sys.argv[1]))["findings"]))' \
  "$OUT/diagnose.json")
((findings >= 1)) || die "diagnose named no effect on data/ (it should: Stribeck, lag, viscous)"
ls -l "$OUT"/*.html

say "Checking the reports in headless Chromium"
# shellcheck disable=SC2046
start check-compare "${CHECK[@]}" "$OUT/compare.html" --expect compare-errors \
  $(per_record validation- LG NLR DNLRX) $(per_record estimation- LG NLR DNLRX) \
  --expect-kind loops-zoom=6 --screenshot "$OUT/compare.png"
# shellcheck disable=SC2046
start check-diagnose "${CHECK[@]}" "$OUT/diagnose.html" $(LOOP_SUFFIX=-1 per_record validation '') \
  $(LOOP_SUFFIX=-2 per_record estimation '') --expect validation-loops-2 \
  --expect estimation-loops-1 --expect-kind "signature=$findings" --screenshot "$OUT/diagnose.png"
start check-validate "${CHECK[@]}" "$OUT/validate.html" --expect validation-time \
  --expect validation-zoom --expect validation-loops --expect validation-loops-zoom \
  --expect validation-sliding

say "Checking the checker on broken reports"
# break NAME PYTHON-EXPRESSION: writes $OUT/broken-NAME.html from the validate report, with the
# expression applied to its text `s`.
break_report() {
  python3 - "$OUT/validate.html" "$OUT/broken-$1.html" "$2" <<'EOF'
import re, sys
s = open(sys.argv[1], encoding="utf-8").read()
def plot(s, pid, f):
    """Applies f to the SVG of plot `pid` only."""
    a = s.index('<svg class="plot" id="%s"' % pid)
    b = s.index("</svg>", a)
    return s[:a] + f(s[a:b]) + s[b:]
t = eval(sys.argv[3])
assert t != s, "the breakage changed nothing"
open(sys.argv[2], "w", encoding="utf-8").write(t)
EOF
}
break_report network \
  's.replace("</main>", "<img alt=\"\" src=\"https://example.com/plot.png\"></main>")'
break_report missing 's.replace("id=\"validation-loops\"", "id=\"validation-hoops\"")'
break_report empty \
  'plot(s, "validation-sliding", lambda p: re.sub(r" d=\"[^\"]*\"", " d=\"\"", p))'
break_report outside \
  'plot(s, "validation-time", lambda p: re.sub(r"([ML])(-?[0-9.]+) ", lambda m: "%s%g " % (m.group(1), float(m.group(2)) + 5000), p))'
break_report invisible \
  'plot(s, "validation-zoom", lambda p: re.sub(r"stroke=\"#[0-9A-Fa-f]{6}\" stroke-width", "stroke=\"#ffffff\" stroke-width", p))'

# The checks of the broken copies run beside the checks of the real reports above; each must
# fail, for the reason it was broken.
BROKEN=()  # NAME:PID of each, its reason in REASON[NAME]
declare -A REASON=()
expect_failure() { # NAME REASON: the check of broken-NAME, in the background
  "${CHECK[@]}" "$OUT/broken-$1.html" --expect validation-loops >"$OUT/broken-$1.log" 2>&1 &
  BROKEN+=("$1:$!")
  REASON[$1]=$2
}
expect_failure network "console error"
expect_failure missing "expected plot validation-loops is missing"
expect_failure empty "validation-sliding, panel force: 0 marks"
expect_failure outside "validation-time, panel force: 0 marks with finite coordinates inside"
expect_failure invisible "validation-zoom, panel force: the screenshot of the plot area is only background"
real=("${NAMES[@]}")
finish
for name in "${real[@]}"; do cat "$OUT/$name.log"; done
for b in "${BROKEN[@]}"; do
  name=${b%%:*}
  log="$OUT/broken-$name.log"
  reason=${REASON[$name]}
  if wait "${b##*:}"; then
    cat "$log"
    die "the checker passed the broken report broken-$name.html"
  fi
  grep -q -- "$reason" "$log" || {
    cat "$log"
    die "the checker failed broken-$name.html, but not for '$reason'"
  }
  printf 'broken-%-10s fails as it should: %s\n' "$name" "$(grep -m1 -- "$reason" "$log")"
done
# The invisible plot keeps its marks in the DOM: only the screenshot caught it.
if grep -q "validation-zoom, panel force: [0-9]* marks" "$OUT/broken-invisible.log"; then
  die "broken-invisible.html: the DOM check should not have seen anything wrong"
fi

say "Reports checked: $OUT/compare.html, $OUT/diagnose.html (screenshots beside them)"

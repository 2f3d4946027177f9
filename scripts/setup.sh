#!/usr/bin/env bash
# Set up, build and run the main job:  bash scripts/setup.sh
#
#   1. installs the Debian packages the build needs (apt-get, only those that are missing),
#   2. configures a Release build with Ninja in build/ and builds it with all cores,
#   3. runs the main job (main_job below) on the records in data/.
#
# Safe to run again: installed packages are skipped and the build is incremental.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
cd "$FRICTION_ROOT"

CLI="$FRICTION_BUILD_DIR/apps/friction-identify"

# ------------------------------------------------------------------------------------------------
# THE MAIN JOB.  The README quotes what this does; keep the two in step.
# Runs from the repository root after a successful build; any failing command fails setup.sh.
# ------------------------------------------------------------------------------------------------
main_job() {
  # The paper's comparison on the bundled pair (data/make-data.sh remakes it): LG, NLR and DNLRX
  # identified on data/estimation.csv, each validated on data/validation.csv.  The document with
  # the identified models goes to out/compare.json, the report (plots, for people) to
  # out/compare.html; the table is printed.
  local f
  for f in data/estimation.csv data/validation.csv; do
    [[ -f "$f" ]] || die "$f is missing"
  done
  mkdir -p out
  "$CLI" compare --data data/estimation.csv --validate data/validation.csv --out out/compare.json \
    --report out/compare.html
  # What the basic model gets wrong there: diagnose names the effects (the record holds Stribeck
  # friction, frictional lag and viscous friction) and extends the model; document in
  # out/diagnose.json, report in out/diagnose.html.  It must name at least one effect.
  echo
  "$CLI" diagnose --data data/estimation.csv --validate data/validation.csv \
    --out out/diagnose.json --report out/diagnose.html
  local named
  named=$(python3 -c 'import json, sys
print(" ".join(f["effect"] for f in json.load(open(sys.argv[1]))["findings"]))' out/diagnose.json)
  [[ -n "$named" ]] || die "diagnose named no effect on data/ (out/diagnose.json)"
  echo "diagnose named: $named"
  echo
  echo "Reports (open in any browser, no network needed):"
  echo "  $FRICTION_ROOT/out/compare.html"
  echo "  $FRICTION_ROOT/out/diagnose.html"
}
# ------------------------------------------------------------------------------------------------

missing_packages() { # missing_packages PACKAGE...: those not installed
  local p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || echo "$p"
  done
}

APT=()  # how to run apt-get here (with sudo when not root); empty when this is not Debian-like
apt_command() {
  if ! command -v dpkg-query >/dev/null 2>&1 || ! command -v apt-get >/dev/null 2>&1; then
    echo "warning: not a Debian-like system (no dpkg-query/apt-get); make sure these are" \
      "installed: ${FRICTION_PACKAGES[*]} ${FRICTION_TEST_PACKAGES[*]}" >&2
    return 0
  fi
  local -a sudo=()
  if ((EUID != 0)); then
    if ! command -v sudo >/dev/null 2>&1; then
      local missing
      missing=$(missing_packages "${FRICTION_PACKAGES[@]}" "${FRICTION_TEST_PACKAGES[@]}")
      [[ -z "$missing" ]] ||
        die "missing packages ($(echo $missing)) and not root and no sudo: install them, then rerun"
      return 0
    fi
    sudo=(sudo)
    [[ -t 0 ]] || sudo=(sudo -n) # no terminal (CI): fail rather than wait for a password
  fi
  APT=("${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get)
}

# The build's packages now; the browser check's (chromium and what it pulls in, the largest
# download) in the background while the build runs, waited for at the end.
TEST_PACKAGES_PID=
TEST_PACKAGES_LOG=
install_packages() {
  apt_command
  ((${#APT[@]} > 0)) || return 0
  local build test
  mapfile -t build < <(missing_packages "${FRICTION_PACKAGES[@]}")
  mapfile -t test < <(missing_packages "${FRICTION_TEST_PACKAGES[@]}")
  if ((${#build[@]} + ${#test[@]} == 0)); then
    say "All $((${#FRICTION_PACKAGES[@]} + ${#FRICTION_TEST_PACKAGES[@]})) Debian packages are installed"
    return 0
  fi
  "${APT[@]}" update
  if ((${#build[@]} > 0)); then
    say "Installing missing packages: ${build[*]}"
    "${APT[@]}" install -y --no-install-recommends "${build[@]}"
  fi
  if ((${#test[@]} > 0)); then
    TEST_PACKAGES_LOG=$(mktemp "${TMPDIR:-/tmp}/friction-packages.XXXXXX")
    say "Installing ${test[*]} in the background (for run-tests.sh; log: $TEST_PACKAGES_LOG)"
    "${APT[@]}" install -y --no-install-recommends "${test[@]}" >"$TEST_PACKAGES_LOG" 2>&1 &
    TEST_PACKAGES_PID=$!
  fi
}

wait_for_test_packages() {
  [[ -n "$TEST_PACKAGES_PID" ]] || return 0
  wait_for_job TEST_PACKAGES_PID "$TEST_PACKAGES_LOG" "installing ${FRICTION_TEST_PACKAGES[*]} failed"
  rm -f "$TEST_PACKAGES_LOG"
}
# When the build or the main job fails, apt-get is let finish (a dpkg stopped half-way leaves the
# system needing `dpkg --configure -a`).
trap '[[ -z "$TEST_PACKAGES_PID" ]] || wait "$TEST_PACKAGES_PID" 2>/dev/null || true' EXIT

timed "packages" install_packages
timed "configure + build ($FRICTION_BUILD_DIR)" configure_and_build "$FRICTION_BUILD_DIR" \
  -DCMAKE_BUILD_TYPE=Release
say "Main job"
timed "main job" main_job
timed "browser check's packages (installed in the background)" wait_for_test_packages
say "setup.sh done"

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

missing_packages() {
  local p
  for p in "${FRICTION_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || echo "$p"
  done
}

install_packages() {
  if ! command -v dpkg-query >/dev/null 2>&1 || ! command -v apt-get >/dev/null 2>&1; then
    echo "warning: not a Debian-like system (no dpkg-query/apt-get); make sure these are" \
      "installed: ${FRICTION_PACKAGES[*]}" >&2
    return 0
  fi
  local missing
  mapfile -t missing < <(missing_packages)
  if ((${#missing[@]} == 0)); then
    say "All ${#FRICTION_PACKAGES[@]} Debian packages are installed"
    return 0
  fi
  local -a sudo=()
  if ((EUID != 0)); then
    command -v sudo >/dev/null 2>&1 ||
      die "missing packages (${missing[*]}) and not root and no sudo: install them, then rerun"
    sudo=(sudo)
    [[ -t 0 ]] || sudo=(sudo -n) # no terminal (CI): fail rather than wait for a password
  fi
  say "Installing missing packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends \
    "${missing[@]}"
}

timed "packages" install_packages
timed "configure + build ($FRICTION_BUILD_DIR)" configure_and_build "$FRICTION_BUILD_DIR" \
  -DCMAKE_BUILD_TYPE=Release
say "Main job"
timed "main job" main_job
say "setup.sh done"

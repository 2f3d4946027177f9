# Shared by scripts/setup.sh and scripts/run-tests.sh (sourced, not run).
#
# Environment knobs (all optional):
#   FRICTION_BUILD_DIR  build directory of the main build (default: build)
#   FRICTION_JOBS       parallel build jobs (default: number of cores)

FRICTION_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
FRICTION_BUILD_DIR="${FRICTION_BUILD_DIR:-build}"
FRICTION_JOBS="${FRICTION_JOBS:-$(nproc 2>/dev/null || echo 2)}"

# The Debian packages the build and the main job need (README and CI rely on this list); python3
# also for the browser check of the HTML reports (scripts/check-reports.sh).
FRICTION_PACKAGES=(cmake ninja-build g++ libeigen3-dev libceres-dev libnlopt-cxx-dev
  libsundials-dev libgtest-dev libcli11-dev nlohmann-json3-dev libbenchmark-dev python3)
# Needed by run-tests.sh only (the browser check of the reports); setup.sh installs them while
# it builds.
FRICTION_TEST_PACKAGES=(chromium)

say() { printf '\n==> %s\n' "$*"; }
die() {
  printf 'error: %s\n' "$*" >&2
  exit 1
}

# Run "$@" and report how long it took: `timed "label" cmd args...`.
timed() {
  local label=$1 start=$SECONDS
  shift
  "$@"
  printf -- '--- %s: %ds\n' "$label" $((SECONDS - start))
}

# Wait for a job started in the background with its output in LOG; show the log when the job
# failed (and also when it passed, with `always`) and stop with MESSAGE when it failed.
# Usage: wait_for_job VAR LOG MESSAGE [always], VAR naming the variable that holds the job's PID.
# VAR is cleared once the job has ended, not before: an EXIT trap that kills or waits for the jobs
# it finds there still reaches a job interrupted while this waits.
wait_for_job() {
  local -n job_pid=$1
  local log=$2 message=$3 show=${4:-} status=0
  wait "$job_pid" || status=$?
  job_pid=
  if ((status != 0)) || [[ "$show" == always ]]; then cat "$log"; fi
  ((status == 0)) || die "$message"
}

# Configure (only when there is no build yet, or when extra cache options are given) and build.
# Usage: configure_and_build DIR [cmake -D options...]
configure_and_build() {
  local dir=$1
  shift
  if [[ ! -f "$dir/CMakeCache.txt" ]]; then
    say "Configuring $dir (Ninja${*:+, $*})"
    cmake -S "$FRICTION_ROOT" -B "$dir" -G Ninja "$@"
  elif (($# > 0)); then
    # Re-assert the options on an existing build (cheap when nothing changed); keep its generator.
    cmake -S "$FRICTION_ROOT" -B "$dir" "$@" >/dev/null
  fi
  say "Building $dir with $FRICTION_JOBS jobs"
  cmake --build "$dir" --parallel "$FRICTION_JOBS"
}

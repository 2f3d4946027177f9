#!/usr/bin/env bash
# Run the tests:  bash scripts/run-tests.sh
#
#   1. builds build/ if needed (configures it like setup.sh when it does not exist),
#   2. checks that every compile of the project's own sources has -Wall -Wextra -Wpedantic -Werror,
#   3. runs the GoogleTest suite with ctest,
#   4. the browser check of the HTML reports (scripts/check-reports.sh): the reports of compare
#      and diagnose on data/ rendered by headless Chromium, and the checker shown to fail on
#      deliberately broken reports,
#   5. install test: installs into a temporary prefix, builds examples/cmake-project against it
#      with find_package(friction CONFIG REQUIRED) and runs it,
#   6. the suite again under AddressSanitizer + UndefinedBehaviorSanitizer (build-asan/), except
#      the tests labelled "long" (the statistical studies: many fits of the same code paths, which
#      the Release pass runs and which would take most of CI's time under ASan); their programs
#      are not built there (FRICTION_BUILD_LONG_TESTS=OFF).
#      FRICTION_SKIP_SANITIZERS=1 skips this pass (CI always runs it).
#   7. ThreadSanitizer on the concurrency tests (build-tsan/, only the three test programs that
#      hold them): diagnose's candidates on four threads, LG's global stages on concurrent
#      threads, compare's three methods on concurrent threads (test_concurrency).
#      FRICTION_SKIP_SANITIZERS=1 skips it too.
#   Steps 6 and 7 start in the background when step 3 has passed, and so run beside steps 4 and 5.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
cd "$FRICTION_ROOT"

ASAN_BUILD_DIR="${FRICTION_ASAN_BUILD_DIR:-build-asan}"
TSAN_BUILD_DIR="${FRICTION_TSAN_BUILD_DIR:-build-tsan}"
CTEST_JOBS=2
# The sanitizer builds: -O1 with line tables only (-g1).  File and line are all a sanitizer report
# needs; full debug information of the Ceres/Eigen templates costs compile time (extension_fit.cpp
# under ASan: 58 s with -O2 -g, 46 s with -O2 -g1, 25 s with -O1 -g1).  On two cores the ASan+UBSan
# pass took 286 s to build and 62 s to test at -O1 (1f66459), against 401 s and 57 s at -O2 (the
# clean-clone CI run of 87e59bb); the TSan pass 169 s and 43 s against 237 s and 31 s.  (While
# the fits were slower, the -O1 tests ran longer than the build saved.)
SANITIZER_OPT_FLAGS="-O1 -g1 -DNDEBUG"
# Every build here is a unity build (FRICTION_UNITY_BUILD, CMakeLists.txt says what it saves).

# run_ctest DIR [extra ctest arguments...]
run_ctest() {
  local dir=$1
  shift
  say "ctest in $dir $*"
  ctest --test-dir "$dir" --output-on-failure -j "$CTEST_JOBS" "$@"
}

# Every compile command of a source under src/ apps/ tests/ bench/, or of a unity batch of them,
# must carry the warning flags.
check_warning_flags() {
  say "Checking warning flags of the project's own targets"
  if [[ ! -f "$FRICTION_BUILD_DIR/build.ninja" ]]; then
    echo "skipped: $FRICTION_BUILD_DIR is not a Ninja build"
    return 0
  fi
  local commands bad n
  commands=$(ninja -C "$FRICTION_BUILD_DIR" -t commands |
    grep -E -- ' -c [^ ]*(/(src|apps|tests|bench)/[^ ]*\.cpp|/Unity/unity_[0-9]+_cxx\.cxx)' || true)
  n=$(grep -c . <<<"$commands" || true)
  ((n > 0)) || die "no compile commands found for the project's sources in $FRICTION_BUILD_DIR"
  local flag
  for flag in -Wall -Wextra -Wpedantic -Werror; do
    bad=$(grep -v -- " $flag " <<<"$commands" || true)
    [[ -z "$bad" ]] || die "compiled without $flag:"$'\n'"$bad"
  done
  echo "$n compile commands, all with -Wall -Wextra -Wpedantic -Werror"
}

install_test() {
  INSTALL_TMP=$(mktemp -d "${TMPDIR:-/tmp}/friction-install-test.XXXXXX")
  local tmp=$INSTALL_TMP
  say "Install test: cmake --install $FRICTION_BUILD_DIR --prefix $tmp/prefix"
  cmake --install "$FRICTION_BUILD_DIR" --prefix "$tmp/prefix" >"$tmp/install.log" ||
    { cat "$tmp/install.log"; die "cmake --install failed"; }
  echo "installed $(grep -c -- '-- Installing' "$tmp/install.log") files"

  say "Building examples/cmake-project against the installed package"
  # Only the temporary prefix may provide `friction`: no package registries, no source tree.
  cmake -S examples/cmake-project -B "$tmp/example" -G Ninja -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_PREFIX_PATH="$tmp/prefix" -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF \
    -DCMAKE_FIND_USE_SYSTEM_PACKAGE_REGISTRY=OFF
  local found
  found=$(sed -n 's/^friction_DIR:PATH=//p' "$tmp/example/CMakeCache.txt")
  [[ "$found" == "$tmp/prefix/"* ]] || die "example found friction in '$found', not in $tmp/prefix"
  cmake --build "$tmp/example" --parallel "$FRICTION_JOBS"

  say "Running the example"
  local out
  out=$("$tmp/example/friction-compensation") || { echo "$out"; die "the example failed"; }
  echo "$out"
  grep -q '^compensation check: OK$' <<<"$out" || die "the example did not report its check"

  say "Running the example on a saved model (data/true-model.json)"
  out=$("$tmp/example/friction-compensation" data/true-model.json) ||
    { echo "$out"; die "the example failed on the saved model"; }
  echo "$out"
  grep -q '^saved-model check: OK$' <<<"$out" || die "the example did not check the saved model"
}

# The ASan+UBSan build: the library, the CLI and every test program except the studies.
asan_build() {
  configure_and_build "$ASAN_BUILD_DIR" -DFRICTION_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=$SANITIZER_OPT_FLAGS" -DFRICTION_BUILD_BENCHMARKS=OFF \
    -DFRICTION_BUILD_LONG_TESTS=OFF
}

asan_tests() {
  # ctest starts the longest tests first when it has timings of them; a fresh sanitizer build has
  # none, so it takes those the Release pass just measured for the same test names (the ASan+UBSan
  # tests on two cores: 85 s in ctest's own order, 74-75 s longest first).
  local costs=Testing/Temporary/CTestCostData.txt
  if [[ ! -f "$ASAN_BUILD_DIR/$costs" && -f "$FRICTION_BUILD_DIR/$costs" ]]; then
    mkdir -p "$ASAN_BUILD_DIR/Testing/Temporary"
    cp "$FRICTION_BUILD_DIR/$costs" "$ASAN_BUILD_DIR/$costs"
  fi
  ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:detect_stack_use_after_return=1}" \
    UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}" \
    run_ctest "$ASAN_BUILD_DIR" --label-exclude long
}

# The ThreadSanitizer build: the library and the three test programs that hold the concurrency
# tests.  One job of its own (--parallel 1): it runs beside the ASan+UBSan build, and three
# compiles on two cores cost less than the two builds one after the other (the library is one
# translation unit, which alone would leave a core idle for minutes).
thread_sanitizer_build() {
  if [[ ! -f "$TSAN_BUILD_DIR/CMakeCache.txt" ]]; then
    cmake -S "$FRICTION_ROOT" -B "$TSAN_BUILD_DIR" -G Ninja -DFRICTION_TSAN=ON -DFRICTION_COMBINED_TESTS=OFF \
      -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=$SANITIZER_OPT_FLAGS" \
      -DFRICTION_BUILD_BENCHMARKS=OFF -DFRICTION_BUILD_LONG_TESTS=OFF
  fi
  cmake --build "$TSAN_BUILD_DIR" --parallel "${1:-$FRICTION_JOBS}" \
    --target test_diagnose test_lg test_concurrency
}

thread_sanitizer_tests() {
  export TSAN_OPTIONS="${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1}"
  # The three programs at once (their threads leave the two cores half idle one at a time: 40 s in
  # sequence); each one's output is shown when it fails.
  local logs pids=() names=() status=0 i
  logs=$(mktemp -d "${TMPDIR:-/tmp}/friction-tsan.XXXXXX")
  run_tsan() { # run_tsan NAME PROGRAM [ARGS...]
    names+=("$1")
    "${@:2}" >"$logs/$1.log" 2>&1 &
    pids+=($!)
  }
  run_tsan diagnose "$TSAN_BUILD_DIR/tests/test_diagnose" \
    --gtest_filter='Diagnose.TheSameDiagnosisOnOneThreadAndOnSeveral'
  run_tsan lg "$TSAN_BUILD_DIR/tests/test_lg" \
    --gtest_filter='Lg.GlobalStageIsDeterministicOnConcurrentThreads'
  run_tsan concurrency "$TSAN_BUILD_DIR/tests/test_concurrency"
  for i in "${!pids[@]}"; do
    if wait "${pids[$i]}"; then
      echo "${names[$i]}: $(grep -E '^\[  PASSED  \]' "$logs/${names[$i]}.log")"
    else
      cat "$logs/${names[$i]}.log"
      echo "ThreadSanitizer pass: ${names[$i]} failed" >&2
      status=1
    fi
  done
  rm -rf "$logs"
  return "$status"
}

# The sanitizer passes start in the background as soon as the Release tests have passed, beside
# the browser check and the install test (the browser check: 45 s on the clock for 42 CPU-s).
# The ThreadSanitizer pass is one chain of single jobs (the library's one translation unit, then
# three test programs, then their tests): it is the longest path, so it keeps the normal
# priority and runs its tests as soon as they are built.  The ASan+UBSan build runs at a lower
# priority (nice 10) on what is left, then its tests in the foreground.  (With both builds at
# nice 10 and the TSan tests after the ASan+UBSan tests, a clean clone's sanitizer stage took
# 618 s from the start of its builds: the TSan library, starved, finished 591 s in.)  Output goes
# to logs, shown when a step fails.
SANITIZER_START=
start_sanitizer_passes() {
  if [[ "${FRICTION_SKIP_SANITIZERS:-0}" == 1 ]]; then
    say "Skipping the sanitizer passes (FRICTION_SKIP_SANITIZERS=1)"
    return 0
  fi
  mkdir -p "$ASAN_BUILD_DIR" "$TSAN_BUILD_DIR"
  say "In the background: the ASan+UBSan build ($ASAN_BUILD_DIR/build.log), the ThreadSanitizer" \
    "build and tests ($TSAN_BUILD_DIR/build.log, $TSAN_BUILD_DIR/tests.log)"
  SANITIZER_START=$SECONDS
  (
    renice -n 10 -p "$BASHPID" >/dev/null
    asan_build
  ) >"$ASAN_BUILD_DIR/build.log" 2>&1 &
  ASAN_BUILD_PID=$!
  (
    thread_sanitizer_build 1 >"$TSAN_BUILD_DIR/build.log" 2>&1 ||
      { echo "the ThreadSanitizer build failed:"; cat "$TSAN_BUILD_DIR/build.log"; exit 1; }
    printf -- '--- thread sanitizer build (%s): done %ds after the start of the sanitizer passes\n' \
      "$TSAN_BUILD_DIR" $((SECONDS - SANITIZER_START))
    timed "thread sanitizer tests ($TSAN_BUILD_DIR)" thread_sanitizer_tests
  ) >"$TSAN_BUILD_DIR/tests.log" 2>&1 &
  TSAN_PID=$!
}

sanitizer_passes() {
  [[ -n "$SANITIZER_START" ]] || return 0
  say "Waiting for the ASan+UBSan build"
  wait_for_job ASAN_BUILD_PID "$ASAN_BUILD_DIR/build.log" "the ASan+UBSan build failed"
  printf -- '--- ASan+UBSan build (%s, in the background): done %ds after the start of the sanitizer passes\n' \
    "$ASAN_BUILD_DIR" $((SECONDS - SANITIZER_START))
  timed "ASan+UBSan tests ($ASAN_BUILD_DIR)" asan_tests
  say "Waiting for the ThreadSanitizer pass"
  wait_for_job TSAN_PID "$TSAN_BUILD_DIR/tests.log" "the ThreadSanitizer pass failed" always
}

INSTALL_TMP=
ASAN_BUILD_PID=
TSAN_PID=
kill_tree() { # PID and its descendants (the background builds' cmake, ninja and compilers)
  local child
  if command -v pgrep >/dev/null 2>&1; then
    for child in $(pgrep -P "$1" || true); do kill_tree "$child"; done
  fi
  kill "$1" 2>/dev/null || true
}
cleanup() {
  [[ -z "$ASAN_BUILD_PID" ]] || kill_tree "$ASAN_BUILD_PID"
  [[ -z "$TSAN_PID" ]] || kill_tree "$TSAN_PID"
  [[ -z "$INSTALL_TMP" ]] || rm -rf "$INSTALL_TMP"
}
trap cleanup EXIT

total_start=$SECONDS
if [[ -f "$FRICTION_BUILD_DIR/CMakeCache.txt" ]]; then
  timed "build ($FRICTION_BUILD_DIR)" configure_and_build "$FRICTION_BUILD_DIR"
else
  timed "configure + build ($FRICTION_BUILD_DIR)" configure_and_build "$FRICTION_BUILD_DIR" \
    -DCMAKE_BUILD_TYPE=Release
fi
timed "warning flags" check_warning_flags
timed "ctest ($FRICTION_BUILD_DIR)" run_ctest "$FRICTION_BUILD_DIR"
start_sanitizer_passes
timed "browser check of the reports" bash scripts/check-reports.sh
timed "install test" install_test
sanitizer_wait=$SECONDS
timed "sanitizer passes (ASan+UBSan, TSan)" sanitizer_passes
[[ -z "$SANITIZER_START" ]] ||
  printf -- '--- sanitizer stage from its start: %ds (%ds of it after the install test)\n' \
    $((SECONDS - SANITIZER_START)) $((SECONDS - sanitizer_wait))
say "All tests passed ($((SECONDS - total_start))s)"

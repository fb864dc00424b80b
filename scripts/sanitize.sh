#!/usr/bin/env bash
# Builds all host code (library, program, tests) with AddressSanitizer, LeakSanitizer and
# UndefinedBehaviorSanitizer into build-asan/ (cmake -DOCTOVK_SANITIZE=ON) and runs the unit,
# I/O, program and OctoMap oracle tests there through ctest. Fails if a test fails or if any
# sanitizer reports anything, in a test or in a program a test runs (the octovk program under
# test), even where the report goes unseen (the program silences stderr around library calls):
# ASan and LSan write every report to build-asan/sanitizer-logs/, and any file there fails the
# run and is printed; UBSan ends the process with exit status 86, which fails the test.
# Usage: scripts/sanitize.sh [extra cmake args]
# OCTOVK_SANITIZE_TESTS: the test executables to run (default: all ten listed below;
# octovk_oracle_tests takes about 3 of the 4 minutes on 2 CPU cores, the change, cache and
# distance tests about 30 s together, the program's distance and --changes tests a few seconds). Installs nothing: scripts/setup.sh does, and gcc's
# sanitizer runtimes come with it.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$root/build-asan"
all_tests="octovk_tests octovk_cli_tests octovk_cli_query_tests octovk_oracle_tests octovk_tum_tests"
all_tests+=" octovk_change_tests octovk_cache_tests octovk_distance_tests octovk_cli_field_tests"
all_tests+=" octovk_payload_tests"
executables="${OCTOVK_SANITIZE_TESTS:-$all_tests}"
read -ra wanted <<<"$executables"
jobs="$(nproc)"

cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DOCTOVK_SANITIZE=ON \
  -DOCTOVK_BUILD_BENCH=OFF "$@" >/dev/null
# Only what runs: the chosen test executables and the program they start (not the other test
# executables, the Python module, the store's PostgreSQL binary), less for CI to build.
cmake --build "$build" -j "$jobs" --target "${wanted[@]}" octovk_cli

# Keeps every shared library mapped until exit (see the file for why).
keep="$build/keep_libraries_loaded.so"
cc -shared -fPIC -nostdlib -O2 -o "$keep" "$root/tests/sanitizers/keep_libraries_loaded.c"

# The ctest numbers of the chosen executables' tests (one ctest test per gtest test; their names
# carry parameters, spaces and parentheses, so they are picked by number, not by a name regex).
numbers="$(ctest --test-dir "$build" --show-only=json-v1 | python3 -c '
import json, os, sys
want = set(sys.argv[1:])
tests = json.load(sys.stdin)["tests"]
exe = [os.path.basename(t.get("command", [""])[0]) for t in tests]
missing = want - set(exe)
if missing:
    sys.exit("sanitize.sh: no tests found for: " + " ".join(sorted(missing)))
print(",".join(str(i + 1) for i, e in enumerate(exe) if e in want))
' "${wanted[@]}")"

logs="$build/sanitizer-logs"
rm -rf "$logs"
mkdir -p "$logs"
# halt_on_error / -fno-sanitize-recover: the first error ends the process with a non-zero exit.
# log_path: ASan and LSan reports go to $logs/asan.PID, from the tests and every program they run.
# UBSan: gcc links it as a runtime of its own (libubsan) that ignores log_path next to libasan,
# so its report goes to stderr and the process exits 86, a status no test expects of a program.
# LeakSanitizer (part of ASan) checks at exit; lsan.supp names the driver libraries it may
# ignore (each entry says why; none is octovk code). print_suppressions=0: a matched suppression
# alone writes no log. CI=1 (unless set): a missing Vulkan device fails instead of skipping.
export CI="${CI:-1}"
ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:check_initialization_order=1:strict_init_order=1"
export ASAN_OPTIONS="$ASAN_OPTIONS:verify_asan_link_order=0:log_path=$logs/asan"
export LSAN_OPTIONS="suppressions=$root/tests/sanitizers/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:exitcode=86"
export LD_PRELOAD="$keep${LD_PRELOAD:+:$LD_PRELOAD}"
export VK_LOADER_DISABLE_DYNAMIC_LIBRARY_UNLOADING=1

status=0
# -I START,END,STRIDE,N,N,...: an empty range (1 to 0), then the tests by number.
ctest --test-dir "$build" --output-on-failure --no-tests=error -j "$jobs" -I "1,0,1,$numbers" ||
  status=$?
unset LD_PRELOAD

reports=("$logs"/*)
if [ -e "${reports[0]}" ]; then
  for f in "${reports[@]}"; do
    echo "==== sanitizer report: $f ====" >&2
    cat "$f" >&2
  done
  echo "sanitize.sh: ${#reports[@]} sanitizer report(s) (above, and in $logs)" >&2
  exit 1
fi
if [ "$status" -ne 0 ]; then
  echo "sanitize.sh: tests failed under the sanitizers" >&2
  exit "$status"
fi
echo "sanitize.sh: $executables passed under ASan + LSan + UBSan, no reports"

#!/usr/bin/env bash
# Builds the library and the threading tests with ThreadSanitizer into build-tsan/ and runs them
# (tests/threading_test.cpp: four maps on four threads sharing one Context, queries on one map
# while another inserts). Fails on any report that involves octovk's code; the ones that lie
# wholly inside the Vulkan driver or loader, which are not built with TSan and synchronise in
# ways it cannot see, are suppressed by tests/sanitizers/tsan.supp (each entry says why).
# Usage: scripts/tsan.sh [extra cmake args]. Installs nothing: scripts/setup.sh does, and gcc's
# TSan runtime comes with it.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$root/build-tsan"
flags="-fsanitize=thread -fno-omit-frame-pointer -g -O1"
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DOCTOVK_BUILD_BENCH=OFF \
  -DCMAKE_CXX_FLAGS="$flags" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=thread" "$@" >/dev/null
cmake --build "$build" -j "$(nproc)" --target octovk_threading_tests

logs="$build/tsan-logs"
rm -rf "$logs"
mkdir -p "$logs"
# CI=1 (unless set): a missing Vulkan device fails instead of skipping. Reports go to $logs;
# any file there fails the run. second_deadlock_stack: both stacks of a lock-order report.
export CI="${CI:-1}"
export TSAN_OPTIONS="suppressions=$root/tests/sanitizers/tsan.supp:log_path=$logs/tsan:second_deadlock_stack=1:print_suppressions=0"
status=0
"$build/tests/octovk_threading_tests" || status=$?

reports=("$logs"/*)
if [ -e "${reports[0]}" ]; then
  for f in "${reports[@]}"; do
    echo "==== ThreadSanitizer report: $f ====" >&2
    cat "$f" >&2
  done
  echo "tsan.sh: ${#reports[@]} ThreadSanitizer report file(s) (above, and in $logs)" >&2
  exit 1
fi
if [ "$status" -ne 0 ]; then
  echo "tsan.sh: the threading tests failed under ThreadSanitizer (exit $status)" >&2
  exit "$status"
fi
echo "tsan.sh: octovk_threading_tests passed under ThreadSanitizer, no reports"

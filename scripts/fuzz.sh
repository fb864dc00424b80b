#!/usr/bin/env bash
# Fuzzes octovk's file readers with clang's libFuzzer: builds
# octovk_fuzz_{bt,ot,message,graph,tum_lists,depth_png} (tests/fuzz/, -fsanitize=fuzzer,address,undefined)
# into build-fuzz/ with clang, then runs each for OCTOVK_FUZZ_SECONDS (default 60) from the seed
# corpus tests/fuzz/corpus/FORMAT/ with -malloc_limit_mb=256 (the most one allocation may take:
# inputs are at most 16 kB, and a reader's memory must be bounded by its input), -rss_limit_mb=1024
# and -timeout=10. (libFuzzer's default, one allocation up to the 2 GB RSS limit, let a 2.5 kB PNG
# allocate 2 GiB unnoticed: issue 22.) Fails on any crash, sanitizer report, hang (an input over
# 10 s) or allocation over the caps; the input that caused it is kept as build-fuzz/artifacts/FORMAT-crash-*, -timeout-*,
# -oom-* (add it to the regression tests in tests/io_test.cpp, or tests/tum_test.cpp for
# tum_lists and depth_png). Inputs the fuzzer found interesting go to build-fuzz/corpus/FORMAT/,
# never into the repository. Prints how many inputs each target ran.
# Installs clang and its libFuzzer runtime (Debian: clang, libclang-rt-N-dev) when missing.
# Usage: scripts/fuzz.sh [FORMAT...]   (default: bt ot message graph tum_lists depth_png)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="$root/build-fuzz"
seconds="${OCTOVK_FUZZ_SECONDS:-60}"
formats=("$@")
[ ${#formats[@]} -gt 0 ] || formats=(bt ot message graph tum_lists depth_png)

install() {
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "fuzz.sh: error: need root or sudo to install: $*" >&2; exit 1; }
    sudo="sudo"
  fi
  echo "fuzz.sh: installing $*"
  DEBIAN_FRONTEND=noninteractive $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "$@"
}
command -v clang++ >/dev/null || install clang
fuzzer_lib="$(clang++ -print-file-name=libclang_rt.fuzzer-x86_64.a)"
if [ ! -f "$fuzzer_lib" ]; then
  major="$(clang++ -dumpversion | cut -d. -f1)"
  install "libclang-rt-$major-dev"
fi

targets=()
for f in "${formats[@]}"; do targets+=("octovk_fuzz_$f"); done
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DOCTOVK_BUILD_FUZZERS=ON -DOCTOVK_BUILD_TESTS=OFF -DOCTOVK_BUILD_BENCH=OFF >/dev/null
cmake --build "$build" -j "$(nproc)" --target "${targets[@]}"

mkdir -p "$build/artifacts"
failed=()
summary=()
for f in "${formats[@]}"; do
  corpus="$build/corpus/$f"
  log="$build/fuzz-$f.log"
  mkdir -p "$corpus"
  echo "==== fuzz: $f for $seconds s ===="
  status=0
  "$build/tests/fuzz/octovk_fuzz_$f" "$corpus" "$root/tests/fuzz/corpus/$f" \
    -max_total_time="$seconds" -malloc_limit_mb=256 -rss_limit_mb=1024 -timeout=10 \
    -max_len=16384 -print_final_stats=1 -artifact_prefix="$build/artifacts/$f-" >"$log" 2>&1 || status=$?
  runs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)"
  # libFuzzer's -timeout is wall-clock time: on a loaded machine a process can stall past it on
  # an input that takes a millisecond. A timeout counts only if the input also times out alone.
  if [ "$status" -ne 0 ] && grep -aq "libFuzzer: timeout" "$log"; then
    unit="$(sed -n "s/.*Test unit written to \(.*\)$/\1/p" "$log" | tail -1)"
    if [ -n "$unit" ] && "$build/tests/fuzz/octovk_fuzz_$f" -timeout=10 -runs=3 \
      -malloc_limit_mb=256 -rss_limit_mb=1024 "$unit" \
      >"$log.rerun" 2>&1; then
      echo "fuzz.sh: warning: $f: the timeout on $unit did not happen again when the input ran" \
        "alone (3 runs within 10 s each): the machine was loaded; not counted as a hang" >&2
      status=0
    fi
  fi
  if [ "$status" -ne 0 ]; then
    tail -n 40 "$log" >&2
    echo "==== fuzz: $f FAILED (exit $status after ${runs:-?} inputs); log: $log ====" >&2
    failed+=("$f")
  else
    echo "==== fuzz: $f passed: ${runs:-?} inputs in $seconds s, no crash, hang or oversized allocation ===="
  fi
  summary+=("$f: ${runs:-?} inputs, exit $status")
done
printf 'fuzz.sh: %s\n' "${summary[@]}"
if [ ${#failed[@]} -gt 0 ]; then
  printf 'fuzz.sh: FAILED: %s\n' "${failed[@]}" >&2
  exit 1
fi

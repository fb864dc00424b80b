#!/usr/bin/env bash
# Installs what is needed, builds, and runs every test (on lavapipe when there is no GPU):
#   1. the whole suite on the system's Vulkan driver (Debian's lavapipe, Mesa 22.3, without a GPU);
#   2. consumer: the installed package used from another project, through find_package and
#      pkg-config, with the core free of OctoMap (scripts/consumer.sh);
#   3. the whole suite again on a second driver, lavapipe from Mesa 25 (scripts/lavapipe25.sh),
#      because results must not depend on one driver's compiler; it has ray queries, so the
#      tests of castRay's ray-tracing backend must run there (they skip on Mesa 22.3), and run
#      again under the validation layer;
#   4. the whole suite with the Khronos validation layer (core + synchronization validation):
#      any validation message fails the test that caused it;
#   5. the host code under AddressSanitizer and UndefinedBehaviorSanitizer (scripts/sanitize.sh),
#      and the threading tests under ThreadSanitizer (scripts/tsan.sh);
#   6. the .bt / .ot / .graph readers and the TUM RGB-D lists and PNG depth-image reader under
#      libFuzzer, OCTOVK_FUZZ_SECONDS (default 60) each (scripts/fuzz.sh);
#   7. campaign: mutated .bt, .ot, .graph files and TUM folders through the program itself under
#      ulimit -v and a timeout, OCTOVK_CAMPAIGN_SECONDS (default 150) in all
#      (scripts/campaign.py): fails on a crash, hang, leftover temporary, multi-line error, an
#      existing output changed by a failed run, or an image outside a TUM folder accepted.
# Fails if any of them fails, or if a driver it needs is unavailable. With CI set, a missing
# Vulkan device fails the Vulkan tests (and the consumer) instead of skipping them.
# OCTOVK_TEST_STEPS (default "system consumer mesa25 validation sanitize tsan fuzz campaign") picks
# steps, e.g.
# "system".
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
steps="${OCTOVK_TEST_STEPS:-system consumer mesa25 validation sanitize tsan fuzz campaign}"
"$root/scripts/setup.sh"
"$root/scripts/build.sh"
jobs="$(nproc)"
failed=()

step() { case " $steps " in *" $1 "*) return 0 ;; *) return 1 ;; esac; }
run_suite() {  # NAME, then VAR=VALUE words (no spaces) of the environment to run ctest in
  # ($ctest_select: extra ctest arguments that pick tests, e.g. -R REGEX)
  local name="$1"
  shift
  echo "==== tests: $name ===="
  local t0=$SECONDS
  # shellcheck disable=SC2086  # ctest_select is split into words on purpose
  if (cd "$root/build" && env "$@" ctest --output-on-failure -j "$jobs" ${ctest_select:-}); then
    echo "==== tests: $name passed ($((SECONDS - t0)) s) ===="
  else
    echo "==== tests: $name FAILED ($((SECONDS - t0)) s) ====" >&2
    failed+=("$name")
  fi
}

if step system; then
  # With a GPU present this runs on it; on a machine without one, on the system's lavapipe.
  run_suite "system driver"
fi
if step consumer; then
  echo "==== consumer: the installed package from another project ===="
  t0=$SECONDS
  if "$root/scripts/consumer.sh" "$root/build"; then
    echo "==== consumer passed ($((SECONDS - t0)) s) ===="
  else
    echo "==== consumer FAILED ($((SECONDS - t0)) s) ====" >&2
    failed+=("consumer")
  fi
fi
if step mesa25; then
  if "$root/scripts/lavapipe25.sh" "$root/build/mesa25"; then
    # env.sh sets VK_DRIVER_FILES, LD_LIBRARY_PATH and OCTOVK_EXPECT_DRIVER (the tests fail if
    # the device they get is not that driver). This lavapipe has ray queries and ray-tracing
    # pipelines: the tests of both ray-tracing paths must run here, not skip
    # (OCTOVK_EXPECT_RAY_QUERY).
    # shellcheck source=/dev/null
    mesa25_env=$(source "$root/build/mesa25/env.sh" && echo \
      "VK_DRIVER_FILES=$VK_DRIVER_FILES LD_LIBRARY_PATH=$LD_LIBRARY_PATH OCTOVK_EXPECT_DRIVER=$OCTOVK_EXPECT_DRIVER")
    # The ray-tracing tests (castRay and scans through ray tracing, each on both paths: ray
    # queries and the ray-tracing pipeline) run once, under the validation layer: the validation
    # step runs on the system driver, which has no ray tracing. The rest runs without it.
    rt_tests="RayTracing|RayCastingScenarios|CastRays|RtScan"
    # shellcheck disable=SC2086
    ctest_select="-E $rt_tests" run_suite "Mesa 25 lavapipe" $mesa25_env OCTOVK_EXPECT_RAY_QUERY=1
    # shellcheck disable=SC2086
    ctest_select="-R $rt_tests" run_suite \
      "Mesa 25 lavapipe, ray tracing (ray queries and pipelines) under the validation layer" \
      $mesa25_env OCTOVK_EXPECT_RAY_QUERY=1 OCTOVK_VALIDATION=1
  else
    echo "==== tests: Mesa 25 lavapipe UNAVAILABLE: the second driver could not be fetched ====" >&2
    failed+=("Mesa 25 lavapipe (unavailable)")
  fi
fi
if step validation; then
  run_suite "validation layer" OCTOVK_VALIDATION=1
fi
if step sanitize; then
  echo "==== tests: AddressSanitizer + UndefinedBehaviorSanitizer ===="
  if "$root/scripts/sanitize.sh"; then
    echo "==== tests: sanitizers passed ===="
  else
    failed+=("sanitizers")
  fi
fi
if step tsan; then
  echo "==== tests: ThreadSanitizer (maps sharing a Context on several threads) ===="
  if "$root/scripts/tsan.sh"; then
    echo "==== tests: ThreadSanitizer passed ===="
  else
    failed+=("ThreadSanitizer")
  fi
fi
if step fuzz; then
  echo "==== tests: fuzzing the file readers ===="
  if "$root/scripts/fuzz.sh"; then
    echo "==== tests: fuzzing passed ===="
  else
    failed+=("fuzzing")
  fi
fi
if step campaign; then
  # The readers' parsers are fuzzed above; this is the whole program on mutated files, as a user
  # runs it (commands, outputs, temporaries, error lines), at a budget CI's time cap can afford.
  echo "==== tests: mutation campaign through the program ===="
  t0=$SECONDS
  if python3 "$root/scripts/campaign.py" --octovk "$root/build/octovk" \
    --budget-seconds "${OCTOVK_CAMPAIGN_SECONDS:-150}"; then
    echo "==== tests: campaign passed ($((SECONDS - t0)) s) ===="
  else
    echo "==== tests: campaign FAILED ($((SECONDS - t0)) s); mutants in build/campaign-failures/ ====" >&2
    failed+=("campaign")
  fi
fi

if [ ${#failed[@]} -gt 0 ]; then
  printf 'test.sh: FAILED: %s\n' "${failed[@]}" >&2
  exit 1
fi
echo "test.sh: all steps passed: $steps"

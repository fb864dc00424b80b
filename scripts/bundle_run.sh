#!/usr/bin/env bash
# run.sh of a bundle made by scripts/bundle.sh (this file is copied in as run.sh). Runs octovk's
# test suite, the graph2tree parity checks and the benchmark from the bundle's own programs,
# libraries and data, wherever the folder lies, on a machine without Debian's packages.
#
#   ./run.sh info                 the machine, the Vulkan devices, the bundle's build
#   ./run.sh tests [EXE...]       every test executable (or the ones named, e.g. octovk_cli_tests)
#   ./run.sh parity               octovk integrate against graph2tree, byte for byte, timed, with
#                                 the walk and each ray-tracing path the device has (--rays)
#   ./run.sh bench [RUN...]       the benchmark: quick (default), all, fr079_lazy, paper_repeat5,
#                                 paper_repeat5_lazy (the runs of bench/run_all.sh), full (all four),
#                                 or one workload of all: paper, scandat, fr079, scaling, queries
#   ./run.sh all                  info, tests, parity, bench quick
#   ./run.sh lent                 a lent GPU's first command: info, parity, the paper bench, then
#                                 every test executable at once, each step under a time limit,
#                                 and everything packed into $OUT/results.tgz after each step
#
# Results go to $OUT when set (the device tool returns that folder), else to results/ beside this
# script (scratch files and unpacked data to work/ beside it, or $OCTOVK_BUNDLE_WORK): per part a log, the tests' XML (gtest), the parity table, the bench's .md and .json, and
# summary.txt, one line per step with its time, appended as each step ends (a run cut off by a time
# limit keeps what it finished). Each part fits in the device tool's 10 minutes per command on a
# GPU; on lavapipe `tests` takes longer. The exit status is 1 when any step failed.
#
# Environment: OCTOVK_DEVICE picks the device; VK_DRIVER_FILES / VK_ICD_FILENAMES pick the driver
# (when neither is set and NVIDIA's ICD manifest is at /usr/local/nvidia/share/vulkan/icd.d, that
# one is used: the bundle's Vulkan loader would not look there); GTEST_FILTER narrows the tests;
# OCTOVK_EXPECT_RAY_QUERY=1 fails the tests of each ray-tracing path (ray queries, pipelines) the
# device lacks (they skip otherwise; `run.sh info` shows which it has: NVIDIA's GPUs have only
# pipelines, so leave it unset there).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
usage() { sed -n '6,15p' "$0" | sed 's/^# \{0,1\}//'; }
# A bad or help request touches nothing (no results/ or work/ folders made).
case "${1:-all}" in
  info | tests | parity | bench | all | lent) ;;
  -h | --help | help) usage; exit 0 ;;
  *) usage >&2; exit 2 ;;
esac
out="${OUT:-$here/results}"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
# lent: the results in a scratch folder, packed into one file in $OUT (the device tool returns at
# most 8 files, and run.sh writes dozens).
packed=""
if [ "${1:-}" = lent ]; then
  packed="$out/results.tgz"
  out="$(mktemp -d "${TMPDIR:-/tmp}/octovk-results.XXXXXX")/results"
  mkdir -p "$out"
fi
summary="$out/summary.txt"
# Scratch files of the tests and the unpacked bench data (50 MB) stay out of $OUT, which the
# device tool copies back: in work/ beside this script, or under /tmp where the bundle is read-only.
work="${OCTOVK_BUNDLE_WORK:-$here/work}"
mkdir -p "$work" 2>/dev/null && [ -w "$work" ] || work="$(mktemp -d "${TMPDIR:-/tmp}/octovk-bundle.XXXXXX")"

# --- the environment: everything from the bundle ---------------------------------------------

# A device that is missing fails the tests instead of skipping them.
export CI=1
# The loader, OctoMap, libpng, ... from lib/; the C++ runtime from lib/compat/ only when the
# machine's own is older than the one the bundle was built with (a newer one must stay first).
export LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
if ! "$here/bin/octovk" --help >/dev/null 2>&1; then
  export LD_LIBRARY_PATH="$here/lib:$here/lib/compat${LD_LIBRARY_PATH#"$here/lib"}"
fi
nvidia_icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
if [ -z "${VK_DRIVER_FILES:-}${VK_ICD_FILENAMES:-}" ] && [ -f "$nvidia_icd" ]; then
  export VK_DRIVER_FILES="$nvidia_icd"
  # The driver library the manifest names, and those it loads, live beside it on such machines.
  for d in /usr/local/nvidia/lib64 /usr/local/nvidia/lib; do
    [ -d "$d" ] && case ":$LD_LIBRARY_PATH:" in *":$d:"*) ;; *) LD_LIBRARY_PATH="$LD_LIBRARY_PATH:$d" ;; esac
  done
fi
# The validation layer packed by bundle.sh (OCTOVK_VALIDATION=1 turns it on).
export VK_LAYER_PATH="${VK_LAYER_PATH:-$here/lib/layers}"
# The paths the tests were compiled with point into the build machine's checkout: these replace
# them (tests/test_paths.hpp), and the bench's data folder likewise.
export OCTOVK_CLI="$here/bin/octovk"
export OCTOVK_GRAPH2TREE="$here/bin/graph2tree"
export OCTOVK_LOG2GRAPH="$here/bin/log2graph"
export OCTOVK_OCTOMAP_DATA_DIR="$here/data/octomap"
export OCTOVK_SHARED_DATA_DIR="$here/data/tests/data"
export OCTOVK_TEST_TMP="$work/tmp"
export OCTOVK_SOURCE_DIR="$here/data"
export FONTCONFIG_FILE="$here/data/fonts/fonts.conf"  # the pictures' font, packed by bundle.sh
export OCTOVK_BENCH_DATA_DIR="$work/bench-data"
# bzip2 and xz of the bundle where the machine has none (sample_data_test unpacks scan.dat.bz2).
export PATH="$PATH:$here/bin"
mkdir -p "$OCTOVK_TEST_TMP" "$OCTOVK_BENCH_DATA_DIR"

failed=0
now() { date +%s.%N; }
secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", b - a }'; }
note() {  # note STATUS NAME SECONDS DETAIL: one line of summary.txt, also on stderr
  printf '%-4s %-34s %8s s  %s\n' "$1" "$2" "$3" "$4" | tee -a "$summary" >&2
  [ "$1" != FAIL ] || failed=1
}

# The bench's and the parity checks' inputs, unpacked once into work/ (kept for the next run).
unpack_data() {
  local d="$OCTOVK_BENCH_DATA_DIR"
  if [ ! -s "$d/scan.dat" ]; then
    bzip2 -dc "$OCTOVK_OCTOMAP_DATA_DIR/scan.dat.bz2" > "$d/scan.dat.tmp"
    mv "$d/scan.dat.tmp" "$d/scan.dat"
  fi
  if [ ! -s "$d/fr079.graph" ]; then
    xz -dc "$here/data/bench/fr079.graph.xz" > "$d/fr079.graph.tmp"
    mv "$d/fr079.graph.tmp" "$d/fr079.graph"
  fi
}

# --- info ---------------------------------------------------------------------------------------

run_info() {
  {
    echo "== bundle"
    cat "$here/BUILD-INFO.txt"
    echo "== machine"
    uname -srm
    echo "$(getconf GNU_LIBC_VERSION 2>/dev/null || echo "glibc unknown"), $(nproc) cores"
    grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //' || true
    if command -v nvidia-smi >/dev/null; then
      nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
    fi
    echo "VK_DRIVER_FILES=${VK_DRIVER_FILES:-} VK_ICD_FILENAMES=${VK_ICD_FILENAMES:-}"
    echo "LD_LIBRARY_PATH=$LD_LIBRARY_PATH"
    # Tools some tests run through the shell; a missing one fails those tests.
    for tool in python3 bzip2 timeout; do
      echo "$tool: $(command -v "$tool" || echo MISSING)"
    done
    echo "== octovk devices"
  } > "$out/info.txt" 2>&1
  local start status=PASS
  start=$(now)
  "$here/bin/octovk" devices >> "$out/info.txt" 2>&1 || status=FAIL
  cat "$out/info.txt" >&2
  note "$status" "info (octovk devices)" "$(secs "$start" "$(now)")" "$out/info.txt"
}

# --- tests --------------------------------------------------------------------------------------

xml_count() {  # xml_count FILE ATTRIBUTE: the attribute of <testsuites> in gtest's XML
  sed -n "s/.*<testsuites [^>]*\\b$2=\"\\([0-9]*\\)\".*/\\1/p" "$1" | head -1
}

run_tests() {
  local names=("$@") exe log xml start status rc detail
  if [ ${#names[@]} -eq 0 ]; then
    for exe in "$here"/tests/*; do names+=("$(basename "$exe")"); done
  fi
  mkdir -p "$out/tests"
  for name in "${names[@]}"; do
    exe="$here/tests/$name"
    [ -x "$exe" ] || { note FAIL "tests/$name" 0 "no such test executable"; continue; }
    log="$out/tests/$name.log"
    xml="$out/tests/$name.xml"
    rm -f "$xml"
    start=$(now)
    rc=0
    if [ "$name" = octovk_core_consumer ]; then
      # Not gtest: exit 0 passes, 77 skips (ctest's SKIP_RETURN_CODE), anything else fails.
      "$exe" > "$log" 2>&1 || rc=$?
      case $rc in 0) status=PASS ;; 77) status=SKIP ;; *) status=FAIL ;; esac
      detail="exit $rc"
    else
      (cd "$OCTOVK_TEST_TMP" && "$exe" --gtest_brief=1 --gtest_output="xml:$xml") > "$log" 2>&1 ||
        rc=$?
      if [ -f "$xml" ]; then
        local total failures errors skipped
        total=$(xml_count "$xml" tests)
        failures=$(xml_count "$xml" failures)
        errors=$(xml_count "$xml" errors)
        skipped=$(grep -c 'result="skipped"' "$xml" || true)
        detail="$total tests, $failures failed, $errors errors, $skipped skipped, exit $rc"
      else
        detail="no XML written (crashed?), exit $rc"
      fi
      status=PASS
      [ $rc -eq 0 ] && [ -f "$xml" ] || status=FAIL
    fi
    note "$status" "tests/$name" "$(secs "$start" "$(now)")" "$detail"
    [ "$status" != FAIL ] || tail -n 30 "$log" >&2
  done
}

# --- parity: octovk integrate against graph2tree -----------------------------------------------

parity_case() {  # parity_case NAME GRAPH RESOLUTION [EXTRA graph2tree/octovk option pairs...]
  # (rays WAY: octovk integrate --rays WAY, graph2tree as ever)
  local name="$1" graph="$2" res="$3"
  shift 3
  local dir="$out/parity/$name" mine=() theirs=()
  while [ $# -gt 0 ]; do
    case "$1" in
      max-range) mine+=(--max-range "$2"); theirs+=(-m "$2"); shift 2 ;;
      discretize) mine+=(--discretize); theirs+=(-discretize); shift ;;
      rays) mine+=(--rays "$2"); shift 2 ;;
      *) echo "parity_case: unknown option $1" >&2; exit 2 ;;
    esac
  done
  rm -rf "$dir"
  mkdir -p "$dir"
  local t0 t1 t2 status=PASS detail
  t0=$(now)
  if ! "$here/bin/graph2tree" -i "$graph" -o "$dir/graph2tree.bt" -res "$res" "${theirs[@]}" \
    > "$dir/graph2tree.log" 2>&1; then
    note FAIL "parity/$name" "$(secs "$t0" "$(now)")" "graph2tree failed: $dir/graph2tree.log"
    return
  fi
  t1=$(now)
  if ! "$here/bin/octovk" integrate "$graph" -o "$dir/octovk.bt" -o "$dir/octovk.ot" \
    --resolution "$res" "${mine[@]}" > "$dir/octovk.log" 2>&1; then
    note FAIL "parity/$name" "$(secs "$t1" "$(now)")" "octovk failed: $dir/octovk.log"
    return
  fi
  t2=$(now)
  detail="octovk $(secs "$t1" "$t2") s, graph2tree $(secs "$t0" "$t1") s"
  if cmp -s "$dir/graph2tree.bt" "$dir/octovk.bt" && cmp -s "$dir/graph2tree.bt.ot" "$dir/octovk.ot"; then
    detail="same .bt and .ot; $detail"
    # The outputs are checked: only the logs stay (the FR-079 maps are megabytes each).
    rm -f "$dir"/*.bt "$dir"/*.ot
  else
    status=FAIL
    detail="FILES DIFFER (kept in $dir); $detail"
  fi
  note "$status" "parity/$name" "$(secs "$t0" "$t2")" "$detail"
}

run_parity() {
  unpack_data
  local spherical="$OCTOVK_OCTOMAP_DATA_DIR/spherical_scan.graph"
  local fr079="$OCTOVK_BENCH_DATA_DIR/fr079.graph"
  parity_case spherical_0.1 "$spherical" 0.1
  parity_case spherical_0.05 "$spherical" 0.05
  parity_case spherical_0.1_max_range_2 "$spherical" 0.1 max-range 2
  parity_case spherical_0.1_discretize "$spherical" 0.1 discretize
  # The whole FR-079 sequence (4,934 scans; the tests use its first 200): the timed whole-process
  # comparison of docs/benchmarks.md.
  parity_case fr079_0.1 "$fr079" 0.1
  parity_case fr079_0.05 "$fr079" 0.05
  parity_case fr079_0.1_max_range_10 "$fr079" 0.1 max-range 10
  # Scans through ray tracing, on each path the selected device has (a GPU without ray queries
  # runs the pipeline), and --rays rt, which picks one of them.
  local ways
  ways="$(rt_paths)"
  if [ -z "$ways" ]; then
    note SKIP "parity/--rays rt" 0 "the device traces no rays (run.sh info)"
    return
  fi
  for way in rt $ways; do
    parity_case "spherical_0.1_$way" "$spherical" 0.1 rays "$way"
    parity_case "spherical_0.1_max_range_2_$way" "$spherical" 0.1 max-range 2 rays "$way"
    parity_case "fr079_0.1_$way" "$fr079" 0.1 rays "$way"
  done
}

# The ways the device octovk selects traces rays, as --rays values: rt-query (ray queries),
# rt-pipeline (a ray-tracing pipeline), from `octovk devices`.
rt_paths() {
  local devices index line
  devices="$("$here/bin/octovk" devices 2>/dev/null)" || return 0
  index="$(sed -n 's/^selected: \([0-9]*\):.*/\1/p' <<< "$devices")"
  [ -n "$index" ] || return 0
  line="$(grep "^$index: " <<< "$devices" | head -n 1)"
  case "$line" in *"ray queries"*) echo -n "rt-query " ;; esac
  case "$line" in *"ray-tracing pipelines"*) echo -n "rt-pipeline" ;; esac
}

# --- bench --------------------------------------------------------------------------------------

bench_run() {  # bench_run NAME ARGS...: as bench/run_all.sh's run, tables to NAME.md
  local name="$1" start rc=0
  shift
  mkdir -p "$out/bench"
  start=$(now)
  "$here/bin/octovk_bench" "$@" --json "$out/bench/$name.json" > "$out/bench/$name.md" \
    2> "$out/bench/$name.log" || rc=$?
  local status=PASS
  [ $rc -eq 0 ] || status=FAIL
  note "$status" "bench/$name" "$(secs "$start" "$(now)")" "octovk_bench $* (exit $rc)"
  [ $rc -eq 0 ] || tail -n 20 "$out/bench/$name.log" >&2
}

run_bench() {
  unpack_data
  local runs=("$@")
  [ ${#runs[@]} -gt 0 ] || runs=(quick)
  for r in "${runs[@]}"; do
    case "$r" in
      quick) bench_run results_quick --quick ;;
      all) bench_run results --workload all ;;
      fr079_lazy) bench_run fr079_lazy --workload fr079 --lazy-leaf-boxes ;;
      paper_repeat5) bench_run paper_0.05_repeat5 --workload paper --resolutions 0.05 --repeat 5 ;;
      paper_repeat5_lazy)
        bench_run paper_0.05_repeat5_lazy --workload paper --resolutions 0.05 --repeat 5 \
          --lazy-leaf-boxes
        ;;
      full) run_bench all fr079_lazy paper_repeat5 paper_repeat5_lazy ;;
      # One run of Table I's views at 0.05 m with the ray-tracing paths (about 70 s on an H200).
      paper_lent) bench_run paper_0.05 --workload paper --resolutions 0.05 ;;
      # One workload of `all` alone, for when `all` does not fit one 10-minute command.
      paper | scandat | fr079 | scaling | queries) bench_run "results_$r" --workload "$r" ;;
      *) echo "run.sh: unknown bench run '$r'" >&2; usage >&2; exit 2 ;;
    esac
  done
}

# --- lent: one command for a lent GPU's scarce minutes ----------------------------------------

pack() { [ -z "$packed" ] || tar czf "$packed" -C "$(dirname "$out")" "$(basename "$out")"; }

# Each step under its own limit (seconds, from OCTOVK_LENT_LIMITS "info parity bench tests",
# default "30 150 90 200": about 8 minutes in all, inside the device tool's 10 per command), in
# the order of what is worth most: correctness against graph2tree, Table I, then the suite with
# its 18 executables started at once (OCTOVK_VALIDATION=1 runs it under the validation layer).
run_lent() {
  local limits
  read -ra limits <<< "${OCTOVK_LENT_LIMITS:-30 150 90 200}"
  export OUT="$out"  # each step below is a run.sh of its own, writing into the scratch folder
  # A step that fails leaves its lines in summary.txt, one cut by its limit a line saying so;
  # the next step goes on.
  step() {  # step LIMIT PART ARGS...
    local limit="$1" rc=0
    shift
    timeout "$limit" "$0" "$@" || rc=$?
    [ "$rc" -ne 124 ] || note FAIL "lent: $*" "$limit" "cut by its time limit (OCTOVK_LENT_LIMITS)"
    pack
  }
  step "${limits[0]}" info
  step "${limits[1]}" parity
  step "${limits[2]}" bench paper_lent
  local name pids=()
  for exe in "$here"/tests/*; do
    name="$(basename "$exe")"
    timeout "${limits[3]}" "$0" tests "$name" >/dev/null 2>&1 &
    pids+=($!)
  done
  wait "${pids[@]}" || true
  pack
  grep -v '^==' "$out/summary.txt" >&2 || true
}

# --- main ---------------------------------------------------------------------------------------

part="${1:-all}"
[ $# -eq 0 ] || shift
echo "== $(date -u '+%Y-%m-%d %H:%M:%S UTC') run.sh $part $*" >> "$summary"
case "$part" in
  info) run_info ;;
  tests) run_tests "$@" ;;
  parity) run_parity ;;
  bench) run_bench "$@" ;;
  all) run_info; run_tests; run_parity; run_bench quick ;;
  lent) run_lent ;;
esac
echo "run.sh: results in $out (summary: $summary)" >&2
exit $failed

#!/usr/bin/env bash
# Builds octovk_bench, prepares the data, runs every benchmark and draws the plot.
#
#   bench/run_all.sh            the full run (about 10 minutes on a 2-core machine with lavapipe);
#                               results in bench/results/ (the ones docs/benchmarks.md shows)
#   bench/run_all.sh --quick    a smoke run of about a minute; results in build-bench/results-quick/
#
# Environment: BUILD_DIR (default build-bench), OUT_DIR (see above), OCTOVK_DEVICE (Vulkan device).
# Writes OUT_DIR/{results,fr079_lazy,paper_0.05_repeat5,paper_0.05_repeat5_lazy}.{md,json},
# OUT_DIR/benchmarks.png and
# OUT_DIR/source.txt (the commit, the machine and its load when the run started).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${BUILD_DIR:-$root/build-bench}"
quick=0
[ "${1:-}" = "--quick" ] && quick=1
[ $# -le 1 ] || { echo "usage: bench/run_all.sh [--quick]" >&2; exit 2; }
if [ $quick -eq 1 ]; then out="${OUT_DIR:-$build/results-quick}"; else out="${OUT_DIR:-$root/bench/results}"; fi

"$root/scripts/setup.sh"
command -v gnuplot >/dev/null || {
  echo "run_all: gnuplot is missing: apt-get install gnuplot-nox" >&2
  exit 1
}
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target octovk_bench -j "$(nproc)"
data="$build/bench/data"
"$root/bench/prepare_data.sh" "$data"
mkdir -p "$out"
{
  echo "commit: $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)"
  echo "uncommitted changes in: $(git -C "$root" status --short 2>/dev/null | wc -l) paths"
  echo "date: $(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) cores"
  echo "load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
} > "$out/source.txt"
bench="$build/bench/octovk_bench"
common=(--scandat "$data/scan.dat" --fr079 "$data/fr079.graph")

run() {  # run NAME ARGS...: tables to NAME.md (and the terminal), results to NAME.json
  local name="$1"
  shift
  echo "run_all: octovk_bench $* -> $out/$name.{md,json}" >&2
  "$bench" "${common[@]}" "$@" --json "$out/$name.json" | tee "$out/$name.md"
}

if [ $quick -eq 1 ]; then
  run results --quick
  run fr079_lazy --quick --workload fr079 --lazy-leaf-boxes
  extra=("$out/fr079_lazy.json")
else
  run results --workload all
  # FR-079 again with the leaf boxes rebuilt on demand (what `octovk integrate` does).
  run fr079_lazy --workload fr079 --lazy-leaf-boxes
  # The headline figure (76,800-ray views at 0.05 m) as the median of five runs: with the leaf
  # boxes rebuilt after every scan (the whole pipeline), and as the library does by default.
  run paper_0.05_repeat5 --workload paper --resolutions 0.05 --repeat 5
  run paper_0.05_repeat5_lazy --workload paper --resolutions 0.05 --repeat 5 --lazy-leaf-boxes
  extra=("$out/fr079_lazy.json")
fi
python3 "$root/bench/plot_results.py" "$out/results.json" "$out/benchmarks.png" "${extra[@]}"
echo "load average at end: $(cut -d' ' -f1-3 /proc/loadavg)" >> "$out/source.txt"
echo "run_all: done; results in $out" >&2

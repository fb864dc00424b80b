#!/usr/bin/env bash
# Makes the benchmark's real-data inputs in DATA_DIR (default: build-bench/bench/data):
#   scan.dat     OctoMap's 3D laser scan, from liboctomap-dev's examples (bzip2 -d)
#   fr079.graph  the FR-079 sequence: tests/data/fr079-2d/clf2log.py, then log2graph
#   fr079_500.graph  its first 500 scans, cut with OctoMap's ScanGraph (the store's bench),
#   fr079_500_a.graph, fr079_500_b.graph  scans 0-249 and 250-499 (two writers at once)
#   paper.graph  the paper workload's six views of the synthetic building (bench/building.hpp),
#                with BUILD_DIR/bench/octovk_paper_graph when BUILD_DIR is given (the capped bench)
# Skips files that exist. Needs python3, bzip2, liboctomap-dev and octomap-tools.
# Usage: bench/prepare_data.sh [DATA_DIR] [BUILD_DIR]
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
data_dir="${1:-$root/build-bench/bench/data}"
build_dir="${2:-}"
scan_src="${OCTOVK_SCANDAT_BZ2:-/usr/share/doc/liboctomap-dev/examples/data/scan.dat.bz2}"
fr079_dir="${OCTOVK_FR079_DIR:-$root/tests/data/fr079-2d}"
mkdir -p "$data_dir"

if [ ! -s "$data_dir/scan.dat" ]; then
  [ -f "$scan_src" ] || { echo "prepare_data: $scan_src is missing (install liboctomap-dev)" >&2; exit 1; }
  bzip2 -dc "$scan_src" > "$data_dir/scan.dat.tmp"
  mv "$data_dir/scan.dat.tmp" "$data_dir/scan.dat"
  echo "prepare_data: wrote $data_dir/scan.dat"
fi

if [ ! -s "$data_dir/fr079.graph" ]; then
  for f in clf2log.py fr079.clf.bz2; do
    [ -f "$fr079_dir/$f" ] || { echo "prepare_data: $fr079_dir/$f is missing (set OCTOVK_FR079_DIR)" >&2; exit 1; }
  done
  command -v log2graph >/dev/null || { echo "prepare_data: log2graph not found (install octomap-tools)" >&2; exit 1; }
  python3 "$fr079_dir/clf2log.py" "$fr079_dir/fr079.clf.bz2" "$data_dir/fr079.log"
  # log2graph prints lines per scan: kept in a log, shown only if it fails.
  if ! log2graph "$data_dir/fr079.log" "$data_dir/fr079.graph.tmp" > "$data_dir/log2graph.log" 2>&1; then
    tail -n 20 "$data_dir/log2graph.log" >&2
    echo "prepare_data: log2graph failed" >&2
    exit 1
  fi
  mv "$data_dir/fr079.graph.tmp" "$data_dir/fr079.graph"
  rm -f "$data_dir/fr079.log" "$data_dir/log2graph.log"
  echo "prepare_data: wrote $data_dir/fr079.graph"
fi

if [ ! -s "$data_dir/fr079_500.graph" ] || [ ! -s "$data_dir/fr079_500_b.graph" ]; then
  # A few lines of C++ against liboctomap: ScanGraph reads the graph and writes COUNT nodes from
  # FIRST on (it prints a line per scan: kept out of sight).
  tool=$(mktemp -d /tmp/octovk-cut.XXXXXX)
  cat > "$tool/cut.cpp" <<'CPP'
#include <octomap/octomap.h>
#include <cstdlib>
int main(int argc, char** argv) {
  octomap::ScanGraph in, out;
  in.readBinary(argv[1]);
  const int first = std::atoi(argv[3]), count = std::atoi(argv[4]);
  int i = 0;
  for (auto it = in.begin(); it != in.end(); ++it, ++i)
    if (i >= first && i < first + count)
      out.addNode(new octomap::Pointcloud(*(*it)->scan), (*it)->pose);
  return out.writeBinary(argv[2]) ? 0 : 1;
}
CPP
  # shellcheck disable=SC2046
  g++ -O2 -o "$tool/cut" "$tool/cut.cpp" $(pkg-config --cflags --libs octomap)
  for part in "500 0 500" "500_a 0 250" "500_b 250 250"; do
    read -r name first count <<<"$part"
    "$tool/cut" "$data_dir/fr079.graph" "$data_dir/fr079_$name.graph.tmp" "$first" "$count" \
      > "$tool/log" 2>&1 ||
      { tail -n 20 "$tool/log" >&2; rm -rf "$tool"; echo "prepare_data: cutting fr079_$name failed" >&2; exit 1; }
    mv "$data_dir/fr079_$name.graph.tmp" "$data_dir/fr079_$name.graph"
    echo "prepare_data: wrote $data_dir/fr079_$name.graph"
  done
  rm -rf "$tool"
fi

if [ -n "$build_dir" ] && [ ! -s "$data_dir/paper.graph" ]; then
  tool="$build_dir/bench/octovk_paper_graph"
  [ -x "$tool" ] || { echo "prepare_data: $tool is missing (build the bench)" >&2; exit 1; }
  "$tool" "$data_dir/paper.graph.tmp" > /dev/null
  mv "$data_dir/paper.graph.tmp" "$data_dir/paper.graph"
  echo "prepare_data: wrote $data_dir/paper.graph"
fi

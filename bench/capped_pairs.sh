#!/usr/bin/env bash
# A run under a device-memory cap against the same run in core: interleaved pairs of
# whole-process runs,
#   octovk integrate GRAPH -r RES -q -o in_core.bt
#   octovk integrate GRAPH -r RES -q -o capped.bt --max-device-memory CAP
# CAP: a quarter of what the in-core run holds ("device memory:" of a first in-core run) unless
# given (bytes, or with K/M/G). Prints per pair the two wall times, then the medians, the capped
# run's "in parts:" and "spilled:" lines, and whether both maps are byte-identical to graph2tree's.
# The paper building (issue 31's capped target): bench/prepare_data.sh DIR BUILD writes
# DIR/paper.graph with BUILD/bench/octovk_paper_graph.
# Usage: bench/capped_pairs.sh OCTOVK GRAPH [RES] [PAIRS] [CAP]
set -euo pipefail
octovk=$1 graph=$2 res=${3:-0.05} pairs=${4:-5} cap=${5:-}
work=$(mktemp -d /tmp/octovk-capped-pairs.XXXXXX)
trap 'rm -rf "$work"' EXIT
now() { date +%s.%N; }
if [ -z "$cap" ]; then
  mib=$("$octovk" integrate "$graph" -r "$res" -q -o "$work/in_core.bt" |
    sed -n 's/^device memory: *\([0-9.]*\) MiB.*/\1/p')
  cap=$(echo "$mib * 1048576 / 4" | bc | cut -d. -f1)
  echo "in core: $mib MiB of device memory; the cap: a quarter, $cap bytes"
fi
graph2tree -i "$graph" -o "$work/graph2tree.bt" -res "$res" >/dev/null 2>&1
a_times=() b_times=()
for ((i = 1; i <= pairs; ++i)); do
  s=$(now); "$octovk" integrate "$graph" -r "$res" -q -o "$work/in_core.bt" >/dev/null; e=$(now)
  s2=$(now); "$octovk" integrate "$graph" -r "$res" -q -o "$work/capped.bt" \
    --max-device-memory "$cap" >"$work/summary.txt"; e2=$(now)
  a=$(echo "$e - $s" | bc) b=$(echo "$e2 - $s2" | bc)
  a_times+=("$a") b_times+=("$b")
  echo "pair $i: in-core $a s, capped $b s"
done
median() { printf '%s\n' "$@" | sort -g | awk '{v[NR]=$1} END {print (NR % 2) ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2}'; }
ma=$(median "${a_times[@]}") mb=$(median "${b_times[@]}")
echo "medians: in-core $ma s, capped $mb s: $(echo "scale=2; $mb / $ma" | bc)x"
grep -E '^(device memory|in parts|spilled):' "$work/summary.txt" || true
for m in in_core capped; do
  cmp -s "$work/graph2tree.bt" "$work/$m.bt" && echo "$m: byte-identical to graph2tree" ||
    echo "$m: DIFFERS from graph2tree"
done

#!/usr/bin/env bash
# The map store's cost against an in-core run: interleaved pairs of whole-process runs,
#   octovk integrate GRAPH -r RES -q -o in_core.bt
#   octovk integrate GRAPH -r RES -q -o stored.bt --store STORE   (a fresh store each time)
# printing per pair the two wall times and the store's "store time:" line, then the medians and
# whether the two maps are byte-identical. STORE: an SQLite file (default: in a temporary
# folder), or a PostgreSQL URI whose database is dropped and made again before each run (give
# PGBIN, the folder of dropdb/createdb, and the server's -h/-U through PGHOST/PGUSER).
# Usage: bench/store_pairs.sh OCTOVK GRAPH [RES] [PAIRS] [STORE]
set -euo pipefail
octovk=$1 graph=$2 res=${3:-0.05} pairs=${4:-5} store=${5:-}
work=$(mktemp -d /tmp/octovk-store-pairs.XXXXXX)
trap 'rm -rf "$work"' EXIT
[ -n "$store" ] || store="$work/p.sqlite"
# shellcheck source=bench/store_common.sh
source "$(dirname "$0")/store_common.sh"
now() { date +%s.%N; }
a_times=() b_times=()
for ((i = 1; i <= pairs; ++i)); do
  s=$(now); "$octovk" integrate "$graph" -r "$res" -q -o "$work/in_core.bt" >/dev/null; e=$(now)
  fresh_store "$store"
  s2=$(now); "$octovk" integrate "$graph" -r "$res" -q -o "$work/stored.bt" --store "$store" \
    >"$work/summary.txt"; e2=$(now)
  a=$(echo "$e - $s" | bc) b=$(echo "$e2 - $s2" | bc)
  a_times+=("$a") b_times+=("$b")
  echo "pair $i: in-core $a s, store $b s; $(grep 'store time' "$work/summary.txt" | sed 's/store time: *//')"
done
median() { printf '%s\n' "$@" | sort -g | awk '{v[NR]=$1} END {print (NR % 2) ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2}'; }
ma=$(median "${a_times[@]}") mb=$(median "${b_times[@]}")
echo "medians: in-core $ma s, store $mb s: $(echo "scale=2; $mb / $ma" | bc)x"
grep 'store writes' "$work/summary.txt"
cmp -s "$work/in_core.bt" "$work/stored.bt" && echo "maps: byte-identical" || echo "maps: DIFFER"

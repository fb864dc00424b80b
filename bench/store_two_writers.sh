#!/usr/bin/env bash
# Two writers into one map at once: `octovk integrate GRAPH_A --store STORE` and the same with
# GRAPH_B, started together into a fresh store; prints the wall time until both ended and each
# run's summary lines about the store (scans committed, reloads and their time, bytes written).
# STORE: a PostgreSQL URI whose database is dropped and made again first (give PGBIN, the folder
# of dropdb/createdb, and the server through PGHOST/PGUSER), or an SQLite file (removed first).
# Usage: bench/store_two_writers.sh OCTOVK GRAPH_A GRAPH_B STORE [RES]
# (bench/prepare_data.sh makes fr079_500_a.graph and fr079_500_b.graph: FR-079's scans 0-249 and
# 250-499.)
set -euo pipefail
octovk=$1 graph_a=$2 graph_b=$3 store=$4 res=${5:-0.05}
work=$(mktemp -d /tmp/octovk-two-writers.XXXXXX)
trap 'rm -rf "$work"' EXIT
# shellcheck source=bench/store_common.sh
source "$(dirname "$0")/store_common.sh"
fresh_store "$store"
start=$(date +%s.%N)
"$octovk" integrate "$graph_a" -r "$res" -q --store "$store" >"$work/a.txt" 2>&1 &
a=$!
"$octovk" integrate "$graph_b" -r "$res" -q --store "$store" >"$work/b.txt" 2>&1 || status_b=$?
wait "$a" || status_a=$?
end=$(date +%s.%N)
echo "both ended after $(echo "$end - $start" | bc) s (exit ${status_a:-0} and ${status_b:-0})"
for run in a b; do
  echo "writer $run:"
  grep -E '^(insert time|store)' "$work/$run.txt" | sed 's/^/  /'
done

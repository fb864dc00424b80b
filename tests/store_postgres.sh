#!/usr/bin/env bash
# The store tests against a real PostgreSQL server: starts a private cluster (initdb in a temporary
# folder, a Unix socket only, no TCP), runs TEST_BINARY's StorePostgres tests with
# OCTOVK_TEST_POSTGRES set to it, and stops and removes the cluster. PostgreSQL refuses to run as
# root, so as root the server runs as 'nobody' (runuser). Usage: store_postgres.sh TEST_BINARY.
# Exit 77 (a skip) when PostgreSQL is not installed, except under CI, where that fails.
set -euo pipefail
binary=$1
bin=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1 || true)
if [ -z "$bin" ] || [ ! -x "$bin/initdb" ]; then
  if [ -n "${CI:-}" ] && [ "${CI:-}" != 0 ] && [ "${CI:-}" != false ]; then
    echo "store_postgres: PostgreSQL missing under CI: apt-get install postgresql" >&2
    exit 1
  fi
  echo "store_postgres: PostgreSQL missing (apt-get install postgresql): skipped" >&2
  exit 77
fi
dir=$(mktemp -d /tmp/octovk-pg.XXXXXX)
as_server() {
  if [ "$(id -u)" = 0 ]; then runuser -u nobody -- "$@"; else "$@"; fi
}
[ "$(id -u)" = 0 ] && chown nobody "$dir"
stop() {
  as_server "$bin/pg_ctl" -D "$dir/data" -m immediate stop >/dev/null 2>&1 || true
  rm -rf "$dir"
}
trap stop EXIT
as_server "$bin/initdb" -D "$dir/data" -A trust -U octovk --no-sync >"$dir/initdb.log" 2>&1 ||
  { cat "$dir/initdb.log" >&2; exit 1; }
as_server "$bin/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 60 \
  -o "-k $dir -c listen_addresses= -F" start >/dev/null ||
  { cat "$dir/server.log" >&2; exit 1; }
as_server "$bin/createdb" -h "$dir" -U octovk octovk_test
export OCTOVK_TEST_POSTGRES="postgresql:///octovk_test?host=$dir&user=octovk"
"$binary" --gtest_filter='StorePostgres*'

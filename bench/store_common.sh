# shellcheck shell=bash
# Sourced by bench/store_pairs.sh and bench/store_two_writers.sh.
# fresh_store STORE: an empty store at STORE. A PostgreSQL URI (postgresql:///DB?...): its
# database dropped and made again (PGBIN: the folder of dropdb/createdb; the server through
# PGHOST/PGUSER). Else an SQLite file: removed with its WAL and shared-memory files.
fresh_store() {
  case "$1" in
    postgresql://*)
      local db=${1#postgresql:///}
      db=${db%%\?*}
      "$PGBIN/dropdb" --if-exists "$db"
      "$PGBIN/createdb" "$db"
      ;;
    *) rm -f "$1" "$1-wal" "$1-shm" ;;
  esac
}

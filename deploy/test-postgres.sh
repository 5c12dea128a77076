#!/usr/bin/env bash
# A private PostgreSQL server for Kiln's tests: Debian's PostgreSQL 15 (installed if it is
# missing), a new cluster in a temporary folder, on a loopback port, run as the postgres
# user (initdb refuses root). Prints the URL to give the tests as KILN_TEST_POSTGRES; its
# user may create databases, and each test makes its own.
#
#   eval "$(deploy/test-postgres.sh start)"   # exports KILN_TEST_POSTGRES and KILN_TEST_PGDATA
#   deploy/test-postgres.sh stop "$KILN_TEST_PGDATA"
#   deploy/test-postgres.sh restart "$KILN_TEST_PGDATA"   (an outage, for the HA test)
set -euo pipefail
bin() {
    local b
    b=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)
    [ -n "$b" ] && echo "$b"
}
as_pg() {
    if [ "$(id -u)" = 0 ]; then
        su postgres -s /bin/sh -c "$*"
    else
        sh -c "$*"
    fi
}
case "${1:-start}" in
start)
    if [ -z "$(bin)" ]; then
        echo "test-postgres: installing Debian's postgresql" >&2
        apt-get update -qq >/dev/null
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq postgresql >/dev/null
    fi
    pg=$(bin)
    data=$(mktemp -d /tmp/kiln-pg.XXXXXX)
    [ "$(id -u)" = 0 ] && chown postgres "$data"
    port=$(( 30000 + $$ % 20000 ))
    as_pg "'$pg/initdb' -D '$data/db' -U kiln --auth=trust -E UTF8 >'$data/initdb.log' 2>&1"
    as_pg "'$pg/pg_ctl' -D '$data/db' -l '$data/server.log' -w -o \"-p $port -k '$data' -c listen_addresses=127.0.0.1 -c fsync=off -c max_connections=300\" start >/dev/null"
    echo "export KILN_TEST_POSTGRES=postgres://kiln@127.0.0.1:$port/postgres KILN_TEST_PGDATA=$data"
    echo "test-postgres: PostgreSQL on 127.0.0.1:$port (data in $data)" >&2
    ;;
stop)
    as_pg "'$(bin)/pg_ctl' -D '$2/db' -m fast stop >/dev/null" || true
    rm -rf "$2"
    ;;
restart)
    as_pg "'$(bin)/pg_ctl' -D '$2/db' -m immediate -w restart >/dev/null"
    ;;
*)
    echo "usage: $0 start | stop DATA | restart DATA" >&2
    exit 2
    ;;
esac

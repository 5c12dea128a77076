#!/usr/bin/env bash
# A private S3-compatible server for Kiln's tests: moto's server (PyPI `moto[server]`,
# installed if missing) on a loopback port, with a bucket `kiln-test`. Prints the endpoint
# to give the tests as KILN_TEST_S3, and the server's pid.
#
#   eval "$(deploy/test-s3.sh start)"   # exports KILN_TEST_S3 and KILN_TEST_S3_PID
#   deploy/test-s3.sh stop "$KILN_TEST_S3_PID"
set -euo pipefail
case "${1:-start}" in
start)
    if ! command -v moto_server >/dev/null; then
        echo "test-s3: installing moto[server] from PyPI" >&2
        python3 -m pip install -q 'moto[server]' >&2
    fi
    port=$(( 40000 + $$ % 20000 ))
    log=$(mktemp /tmp/kiln-s3.XXXXXX)
    setsid moto_server -H 127.0.0.1 -p "$port" > "$log" 2>&1 < /dev/null &
    pid=$!
    for _ in $(seq 100); do
        curl -sf -o /dev/null "http://127.0.0.1:$port/" && break
        sleep 0.1
    done
    curl -sf -X PUT -o /dev/null "http://127.0.0.1:$port/kiln-test"
    echo "export KILN_TEST_S3=http://127.0.0.1:$port KILN_TEST_S3_PID=$pid"
    echo "test-s3: moto's S3 server on 127.0.0.1:$port (pid $pid, log $log)" >&2
    ;;
stop)
    kill "$2" 2>/dev/null || true
    ;;
*)
    echo "usage: $0 start | stop PID" >&2
    exit 2
    ;;
esac

#!/usr/bin/env bash
# Coordinators that fail over: two coordinators, as on two hosts, each with a data
# directory of its own, share a PostgreSQL job store and an S3 bucket (moto's server),
# and three workers are given both URLs. Mid-job the driver kill -9s whichever
# coordinator leads, three times (a supervisor starts each one again, as systemd or
# Kubernetes would, and it stands by), restarts PostgreSQL once and cuts the S3 server off
# for 10 s (SIGSTOP: connections made, nothing answered). Every takeover must come within
# 10 s of the kill; the job must finish with every tile and the bytes `kiln render`
# writes. The log gives each takeover and how long it took.
#
#   deploy/test-ha.sh     (starts its own PostgreSQL and S3 server with
#                          deploy/test-postgres.sh and deploy/test-s3.sh, or uses
#                          KILN_TEST_POSTGRES and KILN_TEST_S3, restarting and stopping
#                          them where KILN_TEST_PGDATA and KILN_TEST_S3_PID name them;
#                          prints SKIPPED where they cannot be had)
set -euo pipefail
cd "$(dirname "$0")/.."
NAME=test-ha
. deploy/lib.sh
work="$(mktemp -d)"
# The server to restart mid-job: one this script starts, or the caller's (KILN_TEST_PGDATA,
# as .ci/run exports it).
pgdata=${KILN_TEST_PGDATA:-}
own_pg=
s3pid=${KILN_TEST_S3_PID:-}
own_s3=
supervisors=()
cleanup() {
    for p in "${supervisors[@]}"; do kill "$p" 2>/dev/null || true; done
    pkill -TERM -f -- "$work" 2>/dev/null || true
    for _ in $(seq 50); do pgrep -f -- "$work" >/dev/null || break; sleep 0.2; done
    pkill -KILL -f -- "$work" 2>/dev/null || true
    wait 2>/dev/null || true
    [ -n "$s3pid" ] && kill -CONT "$s3pid" 2>/dev/null
    [ -n "$own_pg" ] && deploy/test-postgres.sh stop "$pgdata"
    [ -n "$own_s3" ] && deploy/test-s3.sh stop "$s3pid"
    [ -n "${KILN_KEEP_LOGS:-}" ] && cp "$work"/*.log "$KILN_KEEP_LOGS"/ 2>/dev/null
    rm -rf "$work" 2>/dev/null || echo "$NAME: could not remove $work (left behind)"
}
trap cleanup EXIT

if [ -z "${KILN_TEST_POSTGRES:-}" ]; then
    if ! env=$(deploy/test-postgres.sh start 2>/dev/null); then
        echo "test-ha: SKIPPED: no PostgreSQL server here and none could be started"
        exit 0
    fi
    eval "$env"
    pgdata=$KILN_TEST_PGDATA
    own_pg=1
fi
if [ -z "${KILN_TEST_S3:-}" ]; then
    if ! env=$(deploy/test-s3.sh start 2>/dev/null); then
        echo "test-ha: SKIPPED: no S3 server here and none could be started"
        exit 0
    fi
    eval "$env"
    s3pid=$KILN_TEST_S3_PID
    own_s3=1
fi
export AWS_ENDPOINT=$KILN_TEST_S3 AWS_ACCESS_KEY_ID=kiln AWS_SECRET_ACCESS_KEY=kiln AWS_REGION=us-east-1
objects="s3://kiln-test/ha-$$"
db=kiln_ha_$$
psql -q "$KILN_TEST_POSTGRES" -c "CREATE DATABASE $db" >/dev/null
store="${KILN_TEST_POSTGRES%/*}/$db"

cargo build --release --locked --bin kiln >/dev/null 2>&1
kiln="$(pwd)/target/release/kiln"
export KILN_TOKEN="ha-$$-$RANDOM"
base=$(( 20000 + $$ % 20000 ))
ports=($base $((base + 1)))
urls="http://127.0.0.1:${ports[0]},http://127.0.0.1:${ports[1]}"

# supervise N: runs coordinator N, and again whenever it dies; its pid is in $work/cN.pid.
supervise() {
    local n=$1
    while true; do
        RUST_LOG=kiln_farm=info "$kiln" coordinator --listen "127.0.0.1:${ports[$n]}" \
            --data-dir "$work/data$n" --store "$store" --objects "$objects" --lease-ttl 6 \
            >> "$work/c$n.log" 2>&1 &
        echo $! > "$work/c$n.pid"
        wait $! || true
        sleep 8
    done
}
supervise 0 & supervisors+=($!)
supervise 1 & supervisors+=($!)
# The coordinator that leads: the one that answers its health check.
leader() {
    local n
    for n in 0 1; do
        if "$kiln" health --coordinator "http://127.0.0.1:${ports[$n]}" --timeout 1 >/dev/null 2>&1; then
            echo "$n"
            return 0
        fi
    done
    return 1
}
must_wait 30 'leader >/dev/null' "a coordinator to lead"
url="http://127.0.0.1:${ports[$(leader)]}"
step "coordinator $(leader) leads; the other stands by"
for w in 1 2 3; do
    "$kiln" worker --coordinator "$urls" --threads 1 --name "w$w" --cache-dir "$work/cache-w$w" > "$work/w$w.log" 2>&1 &
done

scene=scenes/molten-glass/scene.pbrt
# About a minute of rendering on 2 cores, so that every fault lands mid-job.
args=(--spp 1024 --resolution 288x192 --tile 16)
id=$("$kiln" submit "$scene" --coordinator "$urls" "${args[@]}" | sed 's/.*job //')
step "job $id submitted (${args[*]}) through both URLs"

takeovers=()
# standing_by N: coordinator N's last words are that it stands by.
standing_by() { tail -n 2 "$work/c$1.log" | grep -q "standing by"; }
# kill_leader: kill -9 the coordinator that leads, once the other stands by, and time the
# other's takeover.
kill_leader() {
    local old new start end
    old=$(leader)
    must_wait 60 "standing_by $((1 - old))" "coordinator $((1 - old)) to stand by"
    kill -9 "$(cat "$work/c$old.pid")"
    start=$(date +%s.%N)
    must_wait 15 'new=$(leader) && [ "$new" != "$old" ]' "the standby to take the lead"
    end=$(date +%s.%N)
    local took
    took=$(python3 -c "print(f'{$end - $start:.1f}')")
    takeovers+=("$took")
    url="http://127.0.0.1:${ports[$new]}"
    step "kill -9 coordinator $old: coordinator $new took the lead in $took s; tiles done $(field tiles_done)/$(field tiles_total)"
    if python3 -c "import sys; sys.exit(0 if $took < 10 else 1)"; then :; else
        echo "test-ha: FAILED: the takeover took $took s, not under 10 s"
        exit 1
    fi
}

must_wait 120 '[ "$(field tiles_done)" -ge 10 ]' "the first tiles"
kill_leader
must_wait 120 '[ "$(field tiles_done)" -ge 60 ]' "more tiles"
if [ -n "$pgdata" ]; then
    step "tiles done $(field tiles_done): restarting PostgreSQL (an immediate stop)"
    deploy/test-postgres.sh restart "$pgdata"
    step "PostgreSQL is back; tiles done $(field tiles_done)"
fi
kill_leader
must_wait 120 '[ "$(field tiles_done)" -ge 110 ]' "more tiles"
if [ -n "$s3pid" ]; then
    step "tiles done $(field tiles_done): the S3 server cut off for 10 s"
    kill -STOP "$s3pid"
    sleep 10
    kill -CONT "$s3pid"
    step "the S3 server is back; tiles done $(field tiles_done)"
fi
must_wait 120 '[ "$(field tiles_done)" -ge 150 ]' "more tiles"
kill_leader

# The same scene and settings submitted again are the same job: wait for it and download.
"$kiln" submit "$scene" --coordinator "$urls" "${args[@]}" --wait --quiet -o "$work/farm.exr" >/dev/null
step "job $id done: $(field tiles_done)/$(field tiles_total) tiles, $(field failures) failed attempts"
"$kiln" render "$scene" "${args[@]}" --quiet -o "$work/direct.exr"
if ! cmp -s "$work/farm.exr" "$work/direct.exr"; then
    echo "test-ha: FAILED: the farm's frame differs from kiln render's"
    exit 1
fi
grep -h "took the lead\|standing by\|fetched" "$work"/c*.log | sed "s/\x1b\[[0-9;]*m//g; s/^/$NAME: log: /" || true
step "takeovers in ${takeovers[*]} s; the farm's frame has kiln render's bytes: passed"

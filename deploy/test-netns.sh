#!/usr/bin/env bash
# Hosts that fail: a coordinator and two workers, each in its own network namespace on a
# private bridge (made here with ip netns and veth pairs, nothing outside them touched).
# Mid-job it cuts one worker's link for longer than a lease (the lease expires, the tile is
# lent again, the worker's late upload is refused or identical), then partitions the
# coordinator from every worker for longer than a lease and heals it. The job must finish
# with no tile lost and the bytes `kiln render` writes.
#
#   deploy/test-netns.sh        (needs root and iproute2; prints SKIPPED without)
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "$(id -u)" != 0 ] || ! command -v ip >/dev/null || ! ip netns add "kiln-probe-$$" 2>/dev/null; then
    echo "test-netns: SKIPPED: network namespaces need root and iproute2"
    exit 0
fi
ip netns del "kiln-probe-$$"
NAME=test-netns
. deploy/lib.sh
tag=k$$
sw=$tag-sw
hosts=(coord w1 w2)
work="$(mktemp -d)"
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    # $! of a backgrounded `on` is the subshell, not kiln: end the processes themselves
    # (every one names $work), or they outlive the test for their give-up time.
    pkill -TERM -f -- "$work" 2>/dev/null || true
    for _ in $(seq 50); do pgrep -f -- "$work" >/dev/null || break; sleep 0.2; done
    pkill -KILL -f -- "$work" 2>/dev/null || true
    wait 2>/dev/null || true
    for h in "${hosts[@]}"; do ip netns del "$tag-$h" 2>/dev/null || true; done
    ip netns del "$sw" 2>/dev/null || true
    rm -rf "$work" 2>/dev/null || echo "$NAME: could not remove $work (left behind)"
}
trap cleanup EXIT

cargo build --release --locked --bin kiln >/dev/null 2>&1
kiln="$(pwd)/target/release/kiln"
export KILN_TOKEN="netns-$$"

step "a switch and three hosts on 10.77.0.0/24"
ip netns add "$sw"
ip netns exec "$sw" ip link add br0 type bridge
ip netns exec "$sw" ip link set br0 up
n=1
for h in "${hosts[@]}"; do
    ip netns add "$tag-$h"
    ip link add "$tag-$h" type veth peer name "$tag-$h-p"
    ip link set "$tag-$h" netns "$tag-$h"
    ip link set "$tag-$h-p" netns "$sw"
    ip netns exec "$sw" ip link set "$tag-$h-p" master br0 up
    ip netns exec "$tag-$h" ip link set lo up
    ip netns exec "$tag-$h" ip addr add "10.77.0.$n/24" dev "$tag-$h"
    ip netns exec "$tag-$h" ip link set "$tag-$h" up
    n=$((n + 1))
done
link() { ip netns exec "$sw" ip link set "$tag-$1-p" "$2"; }
on() { local h=$1; shift; ip netns exec "$tag-$h" "$@"; }
url=http://10.77.0.1:7878

on coord "$kiln" coordinator --listen 10.77.0.1:7878 --data-dir "$work/data" --lease-ttl 3 > "$work/coord.log" 2>&1 &
pids+=($!)
for w in w1 w2; do
    on "$w" "$kiln" worker --coordinator "$url" --threads 1 --name "$w" --cache-dir "$work/cache-$w" > "$work/$w.log" 2>&1 &
    pids+=($!)
done
must_wait 30 'on coord "$kiln" health --coordinator "$url" --timeout 1 >/dev/null 2>&1' "the coordinator's health check"

scene=scenes/molten-glass/scene.pbrt
args=(--spp 128 --resolution 360x240 --tile 32)
id=$(on coord "$kiln" submit "$scene" --coordinator "$url" "${args[@]}" | sed 's/.*job //')
step "job $id submitted from the coordinator's host (${args[*]})"
VIA="ip netns exec $tag-coord"

must_wait 60 '[ "$(field tiles_done)" -ge 4 ]' "the first tiles"
step "tiles done $(field tiles_done)/$(field tiles_total): cutting w1's link"
link w1 down
must_wait 30 '[ "$(metric kiln_leases_expired_total)" -ge 1 ]' "w1's lease to expire"
step "w1's lease expired (issued $(metric kiln_leases_issued_total), expired $(metric kiln_leases_expired_total)); tiles done $(field tiles_done); link back after 2 s more"
sleep 2
link w1 up
sleep 3
step "tiles done $(field tiles_done): partitioning the coordinator from every worker for 8 s (leases last 3 s)"
link coord down
sleep 8
link coord up
step "healed: the workers back off and come back"
on coord "$kiln" submit "$scene" --coordinator "$url" "${args[@]}" --wait --quiet -o "$work/farm.exr" >/dev/null 2>&1
step "job $id done: tiles $(field tiles_done)/$(field tiles_total), failed attempts $(field failures); leases issued $(metric kiln_leases_issued_total), expired $(metric kiln_leases_expired_total); tiles accepted $(metric kiln_tiles_accepted_total), rejected $(metric kiln_tiles_rejected_total)"
if [ "$(field tiles_done)" != "$(field tiles_total)" ]; then
    echo "test-netns: FAILED: tiles lost"
    exit 1
fi
"$kiln" render "$scene" "${args[@]}" --quiet -o "$work/direct.exr" 2>/dev/null
if ! cmp -s "$work/farm.exr" "$work/direct.exr"; then
    echo "test-netns: FAILED: the farm's frame differs from kiln render's"
    exit 1
fi
for w in w1 w2; do
    step "$w: $(grep -c 'did not answer' "$work/$w.log" || true) backed-off retries; its other complaints:"
    grep -v 'did not answer' "$work/$w.log" | grep -i 'warn\|error' | sed 's/\x1b\[[0-9;]*m//g; s/^[^ ]* *//' | sort | uniq -c | sed -n 1,5p | sed 's/^/test-netns:     /' || true
done
step "no tile lost, the same bytes as kiln render: passed"

# What deploy/test-*.sh share. Source it after setting NAME (the prefix of every line they
# print); `get`, `field` and `metric` ask the farm at $url with $KILN_TOKEN about job $id,
# through $VIA where set (a command prefix, such as `ip netns exec HOST`).
t0=$(date +%s)
step() { echo "$NAME: [$(( $(date +%s) - t0 )) s] $*"; }
get() { ${VIA:-} curl -sf -H "Authorization: Bearer $KILN_TOKEN" "$url$1" || true; }
field() { get "/v1/jobs/$id" | python3 -c "import json,sys; print(json.load(sys.stdin).get('$1', 0))" 2>/dev/null || echo 0; }
metric() { get /metrics | sed -n "s/^$1 //p"; }
# wait_until SECONDS CONDITION: evaluates CONDITION until it holds; fails after SECONDS.
wait_until() {
    local end=$(( $(date +%s) + $1 ))
    until eval "$2"; do
        [ "$(date +%s)" -lt "$end" ] || return 1
        sleep 0.3
    done
}
# must_wait SECONDS CONDITION WHAT: as wait_until, but the test fails with WHAT.
must_wait() {
    wait_until "$1" "$2" || { echo "$NAME: FAILED: timed out waiting for $3"; exit 1; }
}

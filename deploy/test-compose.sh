#!/usr/bin/env bash
# docker-compose.yml run for real: build the image, bring up a coordinator and two workers,
# submit a job from the host, kill a worker container mid-job, restart the coordinator
# container, and check that the finished frame has the bytes `kiln render` writes; then
# `docker-compose down -v` must leave no container, network or volume behind.
#
#   deploy/test-compose.sh            (needs Docker and docker-compose; prints SKIPPED without)
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v docker >/dev/null || ! docker info >/dev/null 2>&1 || ! command -v docker-compose >/dev/null; then
    echo "test-compose: SKIPPED: no Docker engine or docker-compose on this machine"
    exit 0
fi
NAME=test-compose
. deploy/lib.sh
# The failover variant pulls images this machine cannot: its file is checked, not run
# (deploy/test-ha.sh runs the same failover with processes).
KILN_ENV_FILE=kiln.env.example docker-compose -f deploy/docker-compose.ha.yml config -q
step "deploy/docker-compose.ha.yml is a valid compose file"
project=kiln-ci-$$
work="$(mktemp -d)"
export KILN_IMAGE=kiln:ci KILN_ENV_FILE="$work/kiln.env" KILN_PORT=$(( 20000 + $$ % 20000 ))
export KILN_TOKEN="ci-$$-$RANDOM"
# Short leases, so that a killed worker's tile is lent again within seconds.
printf 'KILN_TOKEN=%s\nKILN_LEASE_TTL=4\n' "$KILN_TOKEN" > "$KILN_ENV_FILE"
compose() { docker-compose -p "$project" -f docker-compose.yml "$@"; }
cleanup() {
    compose down -v --remove-orphans >/dev/null 2>&1 || true
    rm -rf "$work" 2>/dev/null || echo "$NAME: could not remove $work (left behind)"
}
trap cleanup EXIT

step "building the image"
# The release kiln the tests built (built now if it is not there) goes into the image:
# deploy/build-image.sh's static build of the same sources is a second 11-minute build.
cargo build --release --locked --bin kiln >/dev/null 2>&1
kiln=target/release/kiln
deploy/build-image.sh --binary "$kiln" "$KILN_IMAGE"
url="http://127.0.0.1:$KILN_PORT"

step "docker-compose up: a coordinator and two workers"
compose up -d --scale worker=2
must_wait 60 '$kiln health --coordinator "$url" --timeout 2 >/dev/null 2>&1' "the coordinator's health check"

scene=scenes/molten-glass/scene.pbrt
args=(--spp 96 --resolution 360x240 --tile 32)
step "submitting $scene (${args[*]}) from the host"
id=$($kiln submit "$scene" --coordinator "$url" "${args[@]}" | sed 's/.*job //')
must_wait 120 '[ "$(field tiles_done)" -ge 2 ]' "the first tiles"
victim=$(compose ps -q worker | sed -n 1p)
step "tiles done $(field tiles_done)/$(field tiles_total): docker kill worker ${victim:0:12}"
docker kill "$victim" >/dev/null
must_wait 60 '[ "$(metric kiln_leases_expired_total)" -ge 1 ]' "the killed worker's lease to expire"
step "the killed worker's lease expired and its tile is lent again (leases issued $(metric kiln_leases_issued_total), expired $(metric kiln_leases_expired_total)); tiles done $(field tiles_done): docker restart coordinator"
compose restart coordinator >/dev/null
must_wait 60 '$kiln health --coordinator "$url" --timeout 2 >/dev/null 2>&1' "the restarted coordinator"
step "coordinator back: tiles done $(field tiles_done)/$(field tiles_total)"
# The same scene and settings submitted again are the same job: wait for it and download.
$kiln submit "$scene" --coordinator "$url" "${args[@]}" --wait --quiet -o "$work/farm.exr" >/dev/null
step "job $id done: $(field failures) failed attempts"
$kiln render "$scene" "${args[@]}" --quiet -o "$work/direct.exr"
if ! cmp -s "$work/farm.exr" "$work/direct.exr"; then
    echo "test-compose: FAILED: the farm's frame differs from kiln render's"
    exit 1
fi
step "the farm's frame has kiln render's bytes"
compose down -v --remove-orphans >/dev/null 2>&1
left=$(docker ps -aq --filter "label=com.docker.compose.project=$project"; docker volume ls -q --filter "label=com.docker.compose.project=$project"; docker network ls -q --filter "label=com.docker.compose.project=$project")
if [ -n "$left" ]; then
    echo "test-compose: FAILED: docker-compose down -v left: $left"
    exit 1
fi
step "docker-compose down -v left nothing running: passed"

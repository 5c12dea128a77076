#!/usr/bin/env bash
# Runs schemathesis over the coordinator's whole API against a live coordinator that holds a
# finished shot of three frames, so the job, frame and token routes answer with real data
# rather than 404s: `crates/farm/schemathesis-run.sh [MAX_EXAMPLES]` from the repository,
# after `cargo build --release` and `pip install schemathesis`. Exits non-zero on any
# failure schemathesis finds.
set -euo pipefail
cd "$(dirname "$0")"
kiln=../../target/release/kiln
max=${1:-100}
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null; rm -rf "$work"' EXIT
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
url=http://127.0.0.1:$port
export KILN_TOKEN=schemathesis-s3cret
"$kiln" coordinator --listen 127.0.0.1:$port --data-dir "$work/data" > "$work/coordinator.log" 2>&1 &
for _ in $(seq 50); do "$kiln" health --coordinator "$url" 2>/dev/null && break; sleep 0.1; done
"$kiln" worker --coordinator "$url" --threads 1 --name st-worker --cache-dir "$work/cache" 2> "$work/worker.log" &
mkdir -p "$work/shot"
for k in 1 2 3; do
    cat > "$work/shot/f$k.pbrt" <<SCENE
LookAt 0 1 -4  0 0 0  0 1 0
Camera "perspective"
Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 24 ]
WorldBegin
LightSource "infinite" "rgb L" [0.5 0.6 0.7]
Material "diffuse" "rgb reflectance" [0.$k 0.5 0.5]
Shape "sphere" "float radius" 1
SCENE
done
"$kiln" submit "$work"/shot/f*.pbrt --coordinator "$url" --spp 2 --tile 16 --wait -q -o "$work/frames" > "$work/submit.out"
job=$(awk '{print $NF}' "$work/submit.out")
export KILN_SHOT_JOB=$job
cat schemathesis.toml - > "$work/schemathesis.toml" <<CONFIG

# The shot just rendered: its id, and its second frame.
[parameters]
"path.id" = "\${KILN_SHOT_JOB}"
"path.frame" = 1
CONFIG
# First the plain run: every check, identifiers as generated (mostly jobs that do not exist).
schemathesis run "$url/v1/openapi.json" --checks all --max-examples "$max" \
    -H "Authorization: Bearer $KILN_TOKEN" "${@:2}"
# Then against the shot. With its identifiers fixed, a request built to break a path
# parameter is made whole again, so the check that bad data is rejected is the plain run's.
schemathesis --config-file "$work/schemathesis.toml" run "$url/v1/openapi.json" --checks all \
    --exclude-checks negative_data_rejection \
    --max-examples "$max" -H "Authorization: Bearer $KILN_TOKEN" "${@:2}"

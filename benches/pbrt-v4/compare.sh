#!/usr/bin/env bash
# Kiln against pbrt-v4 on the same files: samples per second of the whole process (scene
# load included, both), 2 threads, on reference-scenes/cornell-box and veach-mis at
# 256x256 (or --res), the files' own samplers, depths and spp (or --spp).
#
#   benches/pbrt-v4/compare.sh PBRT_BINARY [--res N] [--spp N] [--repeats N]
#
# pbrt-v4 is not part of Kiln: build it from source outside the repository (see README.md
# beside this script). Kiln is run from target/release/kiln (cargo build --release).
set -euo pipefail
pbrt=${1:?usage: compare.sh PBRT_BINARY [--res N] [--spp N] [--repeats N]}
shift
res=256 spp=64 repeats=3
while [ $# -gt 0 ]; do
    case $1 in
        --res) res=$2; shift 2 ;;
        --spp) spp=$2; shift 2 ;;
        --repeats) repeats=$2; shift 2 ;;
        *) echo "unknown argument $1" >&2; exit 2 ;;
    esac
done
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
kiln=$repo/target/release/kiln
shared=$repo/../shared/reference-scenes
[ -x "$kiln" ] || { echo "no $kiln: run cargo build --release first" >&2; exit 1; }
[ -x "$pbrt" ] || { echo "no pbrt-v4 binary at $pbrt" >&2; exit 1; }
[ -d "$shared" ] || { echo "SKIPPED: $shared is not present (../shared exists beside the checkout and in CI only)"; exit 0; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The best of $repeats wall-clock times of a command, in seconds.
best_time() {
    local best=""
    for _ in $(seq "$repeats"); do
        local s e t
        s=$(date +%s.%N)
        "$@" >/dev/null 2>&1 || { echo "failed: $*" >&2; exit 1; }
        e=$(date +%s.%N)
        t=$(echo "$e - $s" | bc -l)
        if [ -z "$best" ] || [ "$(echo "$t < $best" | bc -l)" = 1 ]; then best=$t; fi
    done
    echo "$best"
}

for name in cornell-box veach-mis; do
    src=$shared/$name
    dst=$work/$name
    mkdir -p "$dst"
    for f in "$src"/*; do ln -s "$f" "$dst/"; done
    rm "$dst/scene.pbrt"
    sed -E -e "s/(\"integer xresolution\" *\[ *)[0-9]+/\1$res/" \
        -e "s/(\"integer yresolution\" *\[ *)[0-9]+/\1$res/" "$src/scene.pbrt" > "$dst/scene.pbrt"
    samples=$((res * res * spp))
    tp=$(best_time "$pbrt" --nthreads 2 --spp "$spp" --outfile "$work/$name-pbrt.exr" "$dst/scene.pbrt")
    tk=$(best_time "$kiln" render "$dst/scene.pbrt" --threads 2 --spp "$spp" -q -o "$work/$name-kiln.exr")
    awk -v n="$name" -v r="$res" -v spp="$spp" -v s="$samples" -v tp="$tp" -v tk="$tk" 'BEGIN {
        printf "%s %dx%d %d spp: pbrt-v4 %.2f s (%.3f M samples/s), kiln %.2f s (%.3f M samples/s): kiln/pbrt-v4 %.2fx (target 5x)\n",
            n, r, r, spp, tp, s / tp / 1e6, tk, s / tk / 1e6, tp / tk }'
done

#!/usr/bin/env bash
# Build the Embree baseline (traverse.c) and run it on MESH RAYS pairs.
#
#   benches/embree/run.sh target/traversal/foo.mesh target/traversal/foo.rays [MESH RAYS ...]
#
# Installs Debian's libembree-dev if no Embree header is found. The binary goes
# to target/embree/traverse (override the folder with EMBREE_BUILD_DIR).
# EMBREE_CONFIG and EMBREE_ROBUST are passed through to traverse (see README.md beside
# this script).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
build_dir="${EMBREE_BUILD_DIR:-$root/target/embree}"

if (( $# == 0 || $# % 2 != 0 )); then
    echo "usage: $0 MESH RAYS [MESH RAYS ...]" >&2
    exit 2
fi

# Install Embree from the distribution if neither major version's header exists.
if [[ ! -f /usr/include/embree4/rtcore.h && ! -f /usr/include/embree3/rtcore.h ]]; then
    echo "# no Embree header found, installing libembree-dev" >&2
    sudo=""
    if (( EUID != 0 )); then sudo="sudo"; fi
    $sudo apt-get update
    $sudo apt-get install -y libembree-dev
fi

# Link against whichever major version is installed (traverse.c picks the
# matching header by itself).
if [[ -f /usr/include/embree4/rtcore.h ]]; then
    lib="-lembree4"
else
    lib="-lembree3"
fi

mkdir -p "$build_dir"
gcc -O2 -std=c11 -Wall -Wextra -o "$build_dir/traverse" "$here/traverse.c" $lib -lm

while (( $# >= 2 )); do
    mesh="$1" rays="$2"
    shift 2
    echo "mesh $mesh"
    echo "ray_file $rays"
    "$build_dir/traverse" "$mesh" "$rays"
    echo
done

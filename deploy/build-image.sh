#!/usr/bin/env bash
# Builds Kiln's container image with no registry: a static `kiln` binary in a FROM-scratch
# image (a non-root user, /data as a volume, nothing else), tagged kiln:local (or $1).
#
#   deploy/build-image.sh [TAG]
#
# The binary is linked statically against glibc (crt-static), so the image needs no libc;
# Kiln's farm speaks plain HTTP, so it carries no CA bundle. deploy/Dockerfile builds the
# same layout from the official Rust image, for machines that can pull it.
set -euo pipefail
cd "$(dirname "$0")/.."
tag="${1:-kiln:local}"
target=x86_64-unknown-linux-gnu
echo "build-image: static kiln for $target"
RUSTFLAGS='-C target-feature=+crt-static' cargo build --release --locked --target "$target" --bin kiln
stage="$(mktemp -d)"
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/rootfs/etc" "$stage/rootfs/data" "$stage/rootfs/tmp"
cp "target/$target/release/kiln" "$stage/rootfs/kiln"
strip "$stage/rootfs/kiln" 2>/dev/null || true
echo 'kiln:x:10001:10001:kiln:/data:/kiln' > "$stage/rootfs/etc/passwd"
echo 'kiln:x:10001:' > "$stage/rootfs/etc/group"
cp deploy/Dockerfile.scratch "$stage/Dockerfile"
docker build --quiet -t "$tag" "$stage" >/dev/null
echo "build-image: $tag ($(docker image inspect -f '{{.Size}}' "$tag") bytes)"

#!/usr/bin/env bash
# Builds Kiln's container image with no registry: a static `kiln` binary in a FROM-scratch
# image (a non-root user, /data as a volume, nothing else), tagged kiln:local (or $1).
#
#   deploy/build-image.sh [TAG]
#   deploy/build-image.sh --binary target/release/kiln [TAG]
#
# The binary is linked statically against glibc (crt-static), so the image needs no libc;
# it trusts https peers only through KILN_TLS_CA, so it carries no CA bundle.
# deploy/Dockerfile builds the same layout from the official Rust image, for machines that
# can pull it.
#
# --binary puts a kiln already built into the image instead, with the shared libraries it
# links (as ldd lists them) at their paths: CI's container tests use the binary its test
# build made, which spares a second release build of the whole workspace (11 minutes on 2
# cores) for another target.
set -euo pipefail
cd "$(dirname "$0")/.."
binary=
if [ "${1:-}" = --binary ]; then
    binary="$2"
    shift 2
fi
tag="${1:-kiln:local}"
stage="$(mktemp -d)"
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/rootfs/etc" "$stage/rootfs/data" "$stage/rootfs/tmp"
if [ -n "$binary" ]; then
    echo "build-image: $binary and the libraries it links"
    cp "$binary" "$stage/rootfs/kiln"
    # Lines of `ldd`: "libc.so.6 => /lib/x86_64-linux-gnu/libc.so.6 (0x...)" and the
    # loader's "/lib64/ld-linux-x86-64.so.2 (0x...)".
    ldd "$binary" | grep -o '/[^ ]*' | while read -r lib; do
        mkdir -p "$stage/rootfs$(dirname "$lib")"
        cp -L "$lib" "$stage/rootfs$lib"
    done
else
    target=x86_64-unknown-linux-gnu
    echo "build-image: static kiln for $target"
    RUSTFLAGS='-C target-feature=+crt-static' cargo build --release --locked --target "$target" --bin kiln
    cp "target/$target/release/kiln" "$stage/rootfs/kiln"
fi
strip "$stage/rootfs/kiln" 2>/dev/null || true
echo 'kiln:x:10001:10001:kiln:/data:/kiln' > "$stage/rootfs/etc/passwd"
echo 'kiln:x:10001:' > "$stage/rootfs/etc/group"
cp deploy/Dockerfile.scratch "$stage/Dockerfile"
docker build --quiet -t "$tag" "$stage" >/dev/null
echo "build-image: $tag ($(docker image inspect -f '{{.Size}}' "$tag") bytes)"

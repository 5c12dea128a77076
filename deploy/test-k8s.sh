#!/usr/bin/env bash
# Validates deploy/k8s against the Kubernetes API schemas of a pinned version, strictly (an
# unknown field is an error), with kubernetes-validate from PyPI; then checks that the
# validator does fail on a broken copy. Nothing here runs a cluster.
#
#   deploy/test-k8s.sh        (prints SKIPPED where kubernetes-validate cannot be installed)
set -euo pipefail
cd "$(dirname "$0")/.."
version=1.37.0
validate() { python3 -m kubernetes_validate "$@"; }
if [ "$(validate --version 2>/dev/null)" != "$version" ]; then
    python3 -m pip install -q "kubernetes-validate==$version" >/dev/null 2>&1 || true
fi
if [ "$(validate --version 2>/dev/null)" != "$version" ]; then
    echo "test-k8s: SKIPPED: kubernetes-validate $version could not be installed"
    exit 0
fi
files=(deploy/k8s/secret.yaml deploy/k8s/coordinator.yaml deploy/k8s/workers.yaml)
validate --strict -k "$version" "${files[@]}"
# The kustomization names exactly those files.
for f in "${files[@]}"; do
    grep -q "^  - $(basename "$f")$" deploy/k8s/kustomization.yaml || { echo "test-k8s: FAILED: kustomization.yaml lacks $f"; exit 1; }
done
broken="$(mktemp --suffix .yaml)"
trap 'rm -f "$broken"' EXIT
sed 's/containerPort: 7878/containerPort: "seventy"/' deploy/k8s/coordinator.yaml > "$broken"
if validate --strict -k "$version" --quiet "$broken" >/dev/null 2>&1; then
    echo "test-k8s: FAILED: a broken manifest validated"
    exit 1
fi
echo "test-k8s: deploy/k8s validates against Kubernetes $version (strict); a broken copy does not: passed"

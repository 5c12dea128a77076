#!/usr/bin/env bash
# Validates deploy/k8s against the Kubernetes API schemas of a pinned version, strictly (an
# unknown field is an error), with kubernetes-validate from PyPI; then checks that the
# validator does fail on a broken copy. The failover variant, deploy/k8s/ha, is validated
# as kustomize would build it: its files, and the coordinator with its JSON patch applied.
# Nothing here runs a cluster.
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
patched="$(mktemp --suffix .yaml)"
trap 'rm -f "$broken" "$patched"' EXIT
# The failover variant: its own files, and deploy/k8s's coordinator under its patch (the
# RFC 6902 operations it uses, add and replace, applied here as kustomize would).
python3 - deploy/k8s/coordinator.yaml deploy/k8s/ha/coordinator-patch.yaml "$patched" <<'PY'
import sys, yaml
docs = list(yaml.safe_load_all(open(sys.argv[1])))
ops = yaml.safe_load(open(sys.argv[2]))
target = next(d for d in docs if d["kind"] == "StatefulSet" and d["metadata"]["name"] == "kiln-coordinator")
for op in ops:
    *parents, last = op["path"].strip("/").split("/")
    node = target
    for key in parents:
        node = node[int(key)] if isinstance(node, list) else node[key]
    if op["op"] == "add" and last == "-":
        node.append(op["value"])
    elif op["op"] in ("add", "replace"):
        if op["op"] == "replace" and (last not in node if isinstance(node, dict) else int(last) >= len(node)):
            sys.exit(f"{op['path']}: nothing there to replace")
        node[int(last) if isinstance(node, list) else last] = op["value"]
    else:
        sys.exit(f"unexpected operation {op['op']}")
assert target["spec"]["replicas"] == 2
yaml.safe_dump_all(docs, open(sys.argv[3], "w"))
PY
validate --strict -k "$version" deploy/k8s/ha/store.yaml deploy/k8s/ha/postgres.yaml "$patched"
for f in store.yaml postgres.yaml coordinator-patch.yaml; do
    grep -q "$f" deploy/k8s/ha/kustomization.yaml || { echo "test-k8s: FAILED: ha/kustomization.yaml lacks $f"; exit 1; }
done
sed 's/containerPort: 7878/containerPort: "seventy"/' deploy/k8s/coordinator.yaml > "$broken"
if validate --strict -k "$version" --quiet "$broken" >/dev/null 2>&1; then
    echo "test-k8s: FAILED: a broken manifest validated"
    exit 1
fi
echo "test-k8s: deploy/k8s and deploy/k8s/ha validate against Kubernetes $version (strict); a broken copy does not: passed"

#!/bin/bash
# gitextract.sh GITDIR REV DEST : extract a tree, skipping blobs missing from the snapshot (listed on stderr as MISSING)
G=$1; REV=$2; D=$3; mkdir -p "$D"
if git --git-dir="$G" archive "$REV" 2>/dev/null | tar -x -C "$D" 2>/dev/null && [ ${PIPESTATUS[0]} -eq 0 ]; then exit 0; fi
git --git-dir="$G" ls-tree -r -z "$REV" | while IFS=$'\t' read -r -d '' meta path; do
  set -- $meta; mode=$1; type=$2; obj=$3
  [ "$type" = blob ] || continue
  mkdir -p "$D/$(dirname "$path")"
  if [ "$mode" = 120000 ]; then
    t=$(git --git-dir="$G" cat-file blob $obj 2>/dev/null) && ln -sfn "$t" "$D/$path" || echo "MISSING $path" >&2
  elif git --git-dir="$G" cat-file blob $obj > "$D/$path" 2>/dev/null; then
    [ "$mode" = 100755 ] && chmod +x "$D/$path"
  else rm -f "$D/$path"; echo "MISSING $path" >&2; fi
done

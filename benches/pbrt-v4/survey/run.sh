#!/bin/bash
# Kiln vs pbrt-v4 survey (README.md beside this script).  Usage:
#   run.sh prep  [scene...]   copy scenes from $SCENE_SOURCES, make stand-ins and survey.pbrt
#   run.sh pbrt  [scene...]   render with pbrt-v4  -> $SURVEY_DIR/out/pbrt/<scene>.{exr,log,time}
#   run.sh kiln  [scene...]   render with Kiln     -> $SURVEY_DIR/out/kiln/<scene>.{exr,log,time}
#   run.sh table              means + ratios       -> $SURVEY_DIR/table.md (and out/means.json)
# No scene names = all 45 in scenes.tsv.  Env: SURVEY_DIR (<repo>/target/pbrt-survey), SCENE_SOURCES
# (prep: folder holding bitterli, pbrt-minus-scenes, shimmer-scenes), PBRT (pbrt-v4 binary, needed
# by `pbrt`), KILN (<repo>/target/release/kiln), KILN_SENSOR_DATA (optional), PYTHON (python3),
# SPP (256), LONG (96, longer film side), TIMEOUT (1200 s per render).
set -u
HERE=$(cd "$(dirname "$0")" && pwd)
REPO=$(cd "$HERE/../../.." && pwd)
die() { echo "run.sh: $*" >&2; exit 2; }
abs() { case $1 in /*) echo "$1" ;; *) echo "$PWD/$1" ;; esac; }
tool() { case $1 in */*) abs "$1" ;; *) command -v "$1" || echo "$1" ;; esac; }

export SURVEY_DIR=$(abs "${SURVEY_DIR:-$REPO/target/pbrt-survey}")
SRCS=${SCENE_SOURCES:+$(abs "$SCENE_SOURCES")}
PY=$(tool "${PYTHON:-python3}")
KILN=$(tool "${KILN:-$REPO/target/release/kiln}")
PBRT=${PBRT:+$(tool "$PBRT")}
if [ -n "${KILN_SENSOR_DATA:-}" ]; then export KILN_SENSOR_DATA=$(abs "$KILN_SENSOR_DATA"); else unset KILN_SENSOR_DATA; fi
export SPP=${SPP:-256} LONG=${LONG:-96} TIMEOUT=${TIMEOUT:-1200}
TSV=$HERE/scenes.tsv

cmd=${1:-}; shift || true
case "$cmd" in prep|pbrt|kiln|table) mkdir -p "$SURVEY_DIR" && cd "$SURVEY_DIR" || exit 1 ;; esac
scenes() { if [ $# -gt 0 ]; then printf '%s\n' "$@"; else cut -f1 "$TSV"; fi; }
field() { awk -F'\t' -v n="$1" -v k="$2" '$1==n{print $k}' "$TSV"; }
main_of() { local m; m=$(dirname "$(field "$1" 3)"); realpath -m "$SURVEY_DIR/scenes/$1/$m/survey.pbrt"; }

source_root() {  # folder with repository $1's files; a bare git dir is extracted (HEAD) once into src/
  local d=$SRCS/$1
  if [ -f "$d/HEAD" ] && [ -d "$d/objects" ]; then
    if [ ! -d "src/$1" ]; then
      mkdir -p src; "$HERE/tools/gitextract.sh" "$d" HEAD "src/$1" 2> "src/$1.missing.txt"
    fi
    echo "$SURVEY_DIR/src/$1"
  elif [ -d "$d" ]; then echo "$d"
  else echo "$1: no folder $d" >&2; return 1; fi
}

prep() {  # fresh copy of the scene (hard links where possible), scan, stand-ins, survey.pbrt
  local n src rel root from
  [ -n "$SRCS" ] || die "set SCENE_SOURCES (see README.md)"
  for n in $(scenes "$@"); do
    src=$(field "$n" 2); rel=$(field "$n" 3); [ -n "$src" ] || { echo "unknown scene $n"; continue; }
    root=$(source_root "${src%%/*}") || continue
    from=$root/${src#*/}; [ -d "$from" ] || { echo "$n: no folder $from"; continue; }
    rm -rf "scenes/$n"; mkdir -p "scenes/$n"
    if ! cp -al "$from/." "scenes/$n/" 2>/dev/null; then  # other file system: plain copy
      rm -rf "scenes/$n"; mkdir -p "scenes/$n"; cp -a "$from/." "scenes/$n/" || continue
    fi
    "$PY" "$HERE/tools/scanrefs.py" "scenes/$n/$rel" > "scenes/$n.refs.txt"
    "$PY" "$HERE/tools/standins.py" "scenes/$n" "scenes/$n.refs.txt" | sed "s|^|$n\t|" > "scenes/$n.standins.txt"
    rm -f "$(main_of "$n")"  # never write through a hard link
    echo "$n: film $("$PY" "$HERE/tools/mkfilm.py" "scenes/$n/$rel" "$(main_of "$n")" "$LONG"), $(wc -l < "scenes/$n.standins.txt") stand-ins"
  done
  for n in $(cut -f1 "$TSV"); do cat "scenes/$n.standins.txt" 2>/dev/null || :; done > STANDINS.txt
}

render() {  # render <pbrt|kiln> scene
  local r=$1 n=$2 f out log t0 t1 rc
  f=$(main_of "$n"); mkdir -p "out/$r"; out=$SURVEY_DIR/out/$r/$n.exr; log=$SURVEY_DIR/out/$r/$n.log
  [ -f "$f" ] || { echo "$n: no $f (run prep)"; return; }
  rm -f "$out"; t0=$(date +%s.%N)
  if [ "$r" = pbrt ]; then
    (cd "$(dirname "$f")" && timeout "$TIMEOUT" nice -n 19 "$PBRT" --quiet --nthreads 2 --spp "$SPP" --seed 0 --outfile "$out" "$f") > "$log" 2>&1
  else
    (cd "$(dirname "$f")" && timeout "$TIMEOUT" nice -n 19 "$KILNBIN" render "$f" --spp "$SPP" --threads 2 -q -o "$out") > "$log" 2>&1
  fi
  rc=$?; t1=$(date +%s.%N)
  awk -v rc=$rc -v a="$t0" -v b="$t1" 'BEGIN { printf "%s %.1f\n", rc, b - a }' > "out/$r/$n.time"
  echo "$r $n rc=$rc $(cut -d' ' -f2 "out/$r/$n.time")s $( [ -f "$out" ] || echo 'NO OUTPUT')"
}

case "$cmd" in
  prep) prep "$@" ;;
  pbrt)
    [ -n "$PBRT" ] || die "set PBRT to the pbrt-v4 binary (see ../README.md)"
    [ -x "$PBRT" ] || die "PBRT=$PBRT is not an executable"
    for n in $(scenes "$@"); do render pbrt "$n"; done ;;
  kiln)
    [ -x "$KILN" ] || die "no Kiln binary at $KILN (cargo build --release, or set KILN)"
    # render with a private copy of the binary so a rebuild mid-survey cannot mix versions
    mkdir -p bin out/kiln; KILNBIN=$SURVEY_DIR/bin/kiln; cp -f "$KILN" "$KILNBIN"
    { echo "binary: $KILN"; echo "sha256: $(sha256sum "$KILNBIN" | cut -d' ' -f1)"
      echo "copied: $(date -Is)"; echo "kiln commit: $(git -C "$REPO" log -1 --format='%h %s' 2>/dev/null)"; } > out/kiln/BINARY.txt
    for n in $(scenes "$@"); do render kiln "$n"; done ;;
  table) "$PY" "$HERE/tools/table.py" ;;
  *) sed -n 2,10p "$0"; exit 2 ;;
esac

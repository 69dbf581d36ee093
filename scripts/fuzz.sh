#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ (clang, -fsanitize=fuzzer,address,undefined) in a build
# directory of their own and runs them one after the other.
#
#   scripts/fuzz.sh [--seconds N] [--runs R] [--target T]... [--build-only] [--jobs J]
#
#   --seconds N   run time per target (default 60)
#   --runs R      stop a target earlier, after R executions (issue 22: 10^6 or 30 min)
#   --target T    only this target (repeatable): osm_xml osm_file overpass g2o kitti mulran
#                 yaml_params graph_dump
#   --build-only  build, do not run
#
# The corpus of each target grows in $OGS_FUZZ_BUILD/corpus/T (default build_ws/fuzz; never in
# the repository). Seeds: fuzz/seeds/T (small files written for this project) plus, when
# ../shared/data is present, files cut from the public datasets at run time (never committed).
# A crash or sanitizer report is kept as $OGS_FUZZ_BUILD/crashes/T/crash-* (replay it with
# `build_ws/fuzz/fuzz_T FILE`); the script then exits non-zero. The last lines are one summary
# row per target: executions, executions/s, corpus size, crashes.
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH   # pyenv's python3 breaks catkin
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="${OGS_FUZZ_BUILD:-$ROOT/build_ws/fuzz}"
DATA="${OGS_SHARED_DATA:-$ROOT/../shared/data}"
LOCK="${OGS_BUILD_LOCK:-/tmp/ogs_build.lock}"
ALL_TARGETS=(osm_xml osm_file overpass g2o kitti mulran yaml_params graph_dump)
SECONDS_PER_TARGET=60
RUNS=-1
JOBS=2
BUILD_ONLY=0
TARGETS=()
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) SECONDS_PER_TARGET="$2"; shift 2 ;;
    --runs) RUNS="$2"; shift 2 ;;
    --target) TARGETS+=("$2"); shift 2 ;;
    --jobs) JOBS="$2"; shift 2 ;;
    --build-only) BUILD_ONLY=1; shift ;;
    -h|--help) sed -n '2,19p' "$0"; exit 0 ;;
    *) echo "fuzz.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[ ${#TARGETS[@]} -eq 0 ] && TARGETS=("${ALL_TARGETS[@]}")
for t in "${TARGETS[@]}"; do
  [[ " ${ALL_TARGETS[*]} " == *" $t "* ]] || { echo "fuzz.sh: unknown target '$t'" >&2; exit 2; }
done

CXX_BIN="$(command -v clang++-14 || command -v clang++ || true)"
[ -n "$CXX_BIN" ] || { echo "fuzz.sh: clang++ (14) is needed for libFuzzer" >&2; exit 2; }

# --- build --------------------------------------------------------------------------------
mkdir -p "$BUILD"
if [ ! -f "$BUILD/CMakeCache.txt" ]; then
  (cd "$BUILD" && CXX="$CXX_BIN" cmake "$ROOT/fuzz" -DCMAKE_BUILD_TYPE=RelWithDebInfo) \
    > "$BUILD/cmake.log" 2>&1 || { cat "$BUILD/cmake.log"; exit 1; }
fi
build_targets=(osm_to_pbf)
for t in "${TARGETS[@]}"; do build_targets+=("fuzz_$t"); done
echo "[fuzz] building ${build_targets[*]} in $BUILD"
# The lock serialises compiles with the other builds on this machine (absent lock: no wait).
if ! flock "$LOCK" nice -n 15 make -C "$BUILD" -j"$JOBS" "${build_targets[@]}" > "$BUILD/build.log" 2>&1; then
  grep -E "error|Error" "$BUILD/build.log" | head -30
  exit 1
fi
[ "$BUILD_ONLY" -eq 1 ] && exit 0

# --- seeds from ../shared/data (cut at run time, outside the repository) -------------------
SHARED_SEEDS="$BUILD/seeds_shared"
rm -rf "$SHARED_SEEDS"
mkdir -p "$SHARED_SEEDS"
prefixed() {  # prefixed BYTE FILE OUT [head args...]: OUT = BYTE followed by (part of) FILE
  local byte="$1" file="$2" out="$3"; shift 3
  [ -f "$file" ] || return 0
  { printf "\\x$byte"; if [ $# -gt 0 ]; then head "$@" "$file"; else cat "$file"; fi; } > "$out"
}
if [ -d "$DATA" ]; then
  for t in "${TARGETS[@]}"; do mkdir -p "$SHARED_SEEDS/$t"; done
  for f in "$DATA"/osm/*.osm; do
    [ -f "$f" ] || continue
    b=$(basename "$f" .osm)
    # The first 16 kB (nodes, a few ways): an execution of the OSM targets costs ~ its size.
    for t in osm_xml overpass; do
      [ -d "$SHARED_SEEDS/$t" ] && head -c 16000 "$f" > "$SHARED_SEEDS/$t/$b.osm"
    done
    prefixed 01 "$f" "$SHARED_SEEDS/osm_file/$b.xml" -c 16000 2>/dev/null || true
  done
  if [ -d "$SHARED_SEEDS/osm_file" ] && [ -f "$DATA/osm/2011_09_26_drive_0005_sync_buildings.osm" ]; then
    "$BUILD/osm_to_pbf" "$DATA/osm/2011_09_26_drive_0005_sync_buildings.osm" "$BUILD/buildings.osm.pbf" &&
      prefixed 00 "$BUILD/buildings.osm.pbf" "$SHARED_SEEDS/osm_file/buildings.pbf"
  fi
  if [ -d "$SHARED_SEEDS/g2o" ]; then
    for f in "$DATA"/posegraph/*.g2o; do
      [ -f "$f" ] && head -n 150 "$f" > "$SHARED_SEEDS/g2o/$(basename "$f")"
    done
  fi
  if [ -d "$SHARED_SEEDS/kitti" ]; then
    prefixed 01 "$DATA/kitti_raw_0005/oxts_frame0.txt" "$SHARED_SEEDS/kitti/oxts_frame0"
    prefixed 02 "$DATA/kitti_raw_0005/calib_2011_09_26.txt" "$SHARED_SEEDS/kitti/calib_rigid"
    prefixed 03 "$DATA/kitti_raw_0005/calib_2011_09_26.txt" "$SHARED_SEEDS/kitti/calib_tracking"
    prefixed 04 "$DATA/kitti00/poses_07_with_time.txt" "$SHARED_SEEDS/kitti/poses_07" -n 20
    prefixed 05 "$DATA/kitti00/000094.bin" "$SHARED_SEEDS/kitti/scan_000094" -c 4096
  fi
fi
if [ -d "$SHARED_SEEDS/overpass" ] && [ -f "$ROOT/fuzz/seeds/overpass/ok_body.osm" ]; then
  # A gzip-encoded answer (the client asks for gzip).
  { printf 'HTTP/1.1 200 OK\r\nContent-Encoding: gzip\r\n\r\n'; gzip -c "$ROOT/fuzz/seeds/overpass/ok_body.osm"; } \
    > "$SHARED_SEEDS/overpass/gzip_answer"
fi
mkdir -p "$SHARED_SEEDS/yaml_params"
cp "$ROOT"/config/*.yaml "$SHARED_SEEDS/yaml_params/" 2>/dev/null || true

# --- run ----------------------------------------------------------------------------------
declare -A DICT=([osm_xml]=osm.dict [overpass]=osm.dict [osm_file]=osm.dict [g2o]=g2o.dict)
declare -A MAX_LEN=([osm_xml]=16384 [overpass]=16384 [osm_file]=16384)
status=0
summary=()
for t in "${TARGETS[@]}"; do
  corpus="$BUILD/corpus/$t"
  crashes="$BUILD/crashes/$t"
  log="$BUILD/logs/$t.log"
  mkdir -p "$corpus" "$crashes" "$(dirname "$log")"
  args=(-max_total_time="$SECONDS_PER_TARGET" -runs="$RUNS" -timeout=20 -rss_limit_mb=2560
        -max_len="${MAX_LEN[$t]:-65536}"
        -print_final_stats=1 -artifact_prefix="$crashes/")
  [ -n "${DICT[$t]:-}" ] && args+=(-dict="$ROOT/fuzz/dicts/${DICT[$t]}")
  seeds=("$ROOT/fuzz/seeds/$t")
  [ -d "$SHARED_SEEDS/$t" ] && seeds+=("$SHARED_SEEDS/$t")
  echo "[fuzz] $t for ${SECONDS_PER_TARGET}s (log $log)"
  before=$(ls "$crashes" | wc -l)
  # The scratch files of the readers go to a directory of this run.
  scratch=$(mktemp -d "${TMPDIR:-/tmp}/ogs_fuzz_run.XXXXXX")
  OGS_FUZZ_TMP="$scratch" ASAN_OPTIONS="detect_leaks=1:allocator_may_return_null=1" \
    UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
    nice -n 10 "$BUILD/fuzz_$t" "${args[@]}" "$corpus" "${seeds[@]}" > "$log" 2>&1
  rc=$?
  rm -rf "$scratch"
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | tail -1 | grep -o '[0-9]*$')
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | tail -1 | grep -o '[0-9]*$')
  found=$(( $(ls "$crashes" | wc -l) - before ))
  if [ $rc -ne 0 ] || [ "$found" -gt 0 ]; then
    status=1
    echo "[fuzz] $t: FAILED (exit $rc); reproducers in $crashes:"
    grep -E "ERROR: |runtime error:|SUMMARY:|Test unit written" "$log" | head -8
  fi
  summary+=("$(printf '%-12s executions %10s  exec/s %7s  corpus %5s  new crashes %s' "$t" "${execs:-?}" "${rate:-?}" "$(ls "$corpus" | wc -l)" "$found")")
done
echo "[fuzz] summary (${SECONDS_PER_TARGET}s per target)"
printf '%s\n' "${summary[@]}"
exit $status

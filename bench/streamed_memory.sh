#!/bin/sh
# Peak memory of a streamed build (issue 19's acceptance: a 4 M-triangle scan
# preprocessed with --memory-limit 128 stays under 192 MiB peak RSS).
#
#   bench/streamed_memory.sh [BUILD_DIR] [TRIANGLES] [LIMIT_MIB] [WORK_DIR]
#
# Generates the scan (binary PLY) in WORK_DIR if it is not there, then builds it
# with /usr/bin/time -v: penumbra-preprocess (no renderer libraries, the tool for
# memory-limited and cluster builds), penumbra (the full CLI, whose shared
# libraries alone take about 130 MiB) and, for comparison, in core. Each output
# is validated (penumbra-preprocess info). Prints one line per run and
# "acceptance: ... PASS|FAIL" for the lean tool against LIMIT + 64 MiB.
# A benchmark, not a test: the numbers depend on the machine and its load.
set -eu
BUILD=${1:-build}
TRIANGLES=${2:-4000000}
LIMIT=${3:-128}
WORK=${4:-/tmp/penumbra-streamed-bench}
mkdir -p "$WORK"
INPUT="$WORK/scan$TRIANGLES.ply"
[ -f "$INPUT" ] || "$BUILD/penumbra-preprocess" generate scan --triangles "$TRIANGLES" -o "$INPUT" > /dev/null
echo "input: $INPUT ($(du -m "$INPUT" | cut -f1) MiB, $TRIANGLES triangles), limit $LIMIT MiB, $(nproc) cores, load $(cut -d' ' -f1 /proc/loadavg)"

run() { # name, output, command...
    name=$1; output=$2; shift 2
    /usr/bin/time -v "$@" > "$WORK/out.txt" 2> "$WORK/time.txt" || { cat "$WORK/time.txt" "$WORK/out.txt"; exit 1; }
    rss=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$WORK/time.txt")
    wall=$(sed -n 's/.*Elapsed (wall clock) time (h:mm:ss or m:ss): //p' "$WORK/time.txt")
    "$BUILD/penumbra-preprocess" info "$output" > /dev/null
    echo "$name: peak RSS $((rss / 1024)) MiB, wall $wall, $(grep -o '[0-9]* chunk(s)' "$WORK/out.txt" || echo 'in core'), $(du -k "$output" | cut -f1) KiB, valid"
    rm -f "$output"
    echo "$rss"
}

lean=$(run "penumbra-preprocess --memory-limit $LIMIT" "$WORK/lean.penumbra" \
    "$BUILD/penumbra-preprocess" preprocess "$INPUT" -o "$WORK/lean.penumbra" --memory-limit "$LIMIT" --quiet)
echo "$lean" | head -1
full=$(run "penumbra --memory-limit $LIMIT" "$WORK/full.penumbra" \
    "$BUILD/penumbra" preprocess "$INPUT" -o "$WORK/full.penumbra" --memory-limit "$LIMIT" --quiet)
echo "$full" | head -1
core=$(run "penumbra-preprocess in core" "$WORK/core.penumbra" \
    "$BUILD/penumbra-preprocess" preprocess "$INPUT" -o "$WORK/core.penumbra" --quiet)
echo "$core" | head -1
rss=$(echo "$lean" | tail -1)
if [ "$rss" -le $(((LIMIT + 64) * 1024)) ]; then verdict=PASS; else verdict=FAIL; fi
echo "acceptance: penumbra-preprocess peak RSS $((rss / 1024)) MiB <= $((LIMIT + 64)) MiB: $verdict"

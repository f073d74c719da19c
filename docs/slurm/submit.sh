#!/bin/bash
# Distributed preprocessing with Slurm: N chunk tasks, then the merge.
#   docs/slurm/submit.sh INPUT OUT_FOLDER MODEL.penumbra N [MAX_PARALLEL]
# Example: docs/slurm/submit.sh /shared/statue.ply /shared/statue-build /shared/statue.penumbra 64 16
set -euo pipefail
if [ $# -lt 4 ]; then
    echo "usage: $0 INPUT OUT_FOLDER MODEL.penumbra CHUNKS [MAX_PARALLEL]" >&2
    exit 1
fi
here=$(cd "$(dirname "$0")" && pwd)
INPUT=$1 OUT=$2 MODEL=$3 CHUNKS=$4 PARALLEL=${5:-$4}
mkdir -p "$OUT"
array=$(sbatch --parsable --array=0-$((CHUNKS - 1))%"$PARALLEL" \
    --export=ALL,INPUT="$INPUT",OUT="$OUT",CHUNKS="$CHUNKS" "$here/penumbra_chunk.sbatch")
merge=$(sbatch --parsable --dependency=afterok:"$array" \
    --export=ALL,OUT="$OUT",CHUNKS="$CHUNKS",MODEL="$MODEL" "$here/penumbra_merge.sbatch")
echo "chunks: job $array (tasks 0..$((CHUNKS - 1))), merge: job $merge -> $MODEL"

#!/bin/bash
# ctest slurm_scripts: runs the job-array scripts without Slurm, each task as its
# own process (as Slurm would), then the merge, on a small generated model.
#   docs/slurm/test_local.sh PENUMBRA_PREPROCESS WORK_FOLDER
set -euo pipefail
tool=$1 work=$2 here=$(cd "$(dirname "$0")" && pwd)
rm -rf "$work" && mkdir -p "$work"
"$tool" generate plant --triangles 20000 -o "$work/plant.ply" > /dev/null
export INPUT="$work/plant.ply" OUT="$work/chunks" CHUNKS=4 MODEL="$work/plant.penumbra" PENUMBRA_PREPROCESS="$tool"
export SLURM_MEM_PER_NODE=256 SLURM_CPUS_PER_TASK=1
pids=()
for ((i = 0; i < CHUNKS; ++i)); do
    SLURM_ARRAY_TASK_ID=$i bash "$here/penumbra_chunk.sbatch" &
    pids+=($!)
done
for pid in "${pids[@]}"; do
    wait "$pid"
done
bash "$here/penumbra_merge.sbatch" | grep -q "triangles        20000 "
[ ! -e "$OUT/chunk0" ]   # the merge removed the chunks
echo "slurm scripts: 4 chunk tasks and the merge gave a valid 20000-triangle model"

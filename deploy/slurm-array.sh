#!/usr/bin/env bash
# A SLURM job array that renders one 4096^3 volume from a 3D model into one Zarr store, as 64
# shards. SLURM gives each task SLURM_ARRAY_TASK_ID (and _MIN, _COUNT); ipfn takes its shard
# from them. A requeued task skips the chunks it already wrote.
#
#   sbatch deploy/slurm-array.sh
#
# MODEL, SIZE, OUT and CHUNK can be set in the environment (sbatch --export=ALL,SIZE=1024 ...); the
# store must be on a file system every node sees.
#SBATCH --job-name=ipfn-volume
#SBATCH --array=0-63
#SBATCH --cpus-per-task=8
#SBATCH --mem=4G
#SBATCH --time=04:00:00
#SBATCH --requeue
set -euo pipefail
MODEL=${MODEL:-volume.ipfn}
SIZE=${SIZE:-4096x4096x4096}
OUT=${OUT:-volume.zarr}
CHUNK=${CHUNK:-64}
exec ipfn synth --model "$MODEL" --size "$SIZE" --seed 1 --out "$OUT" --chunk "$CHUNK" --shard-from-env --quiet

#!/bin/bash
# A sweep spread over a Slurm job array: task i runs part i+1 of N, each into its own
# directory; when all are done, one merge joins them.
#
#   sbatch --array=0-7 examples/slurm/sweep-array.sh crates/pma-studies/models/sweeps/monte_carlo.toml results
#   # afterwards (or as a job with --dependency=afterok:<array job id>):
#   pma-exo sweep merge results/shard-* --out results/merged
#
# A killed or pre-empted task resumes where it stopped when it is run again (same --out):
# the runs already in its runs.jsonl are skipped, a torn last line is redone.
#SBATCH --job-name=pma-exo-sweep
#SBATCH --cpus-per-task=2
#SBATCH --time=01:00:00
#SBATCH --output=slurm-%A_%a.out
set -euo pipefail
sweep=${1:?usage: sbatch --array=0-(N-1) sweep-array.sh SWEEP.toml OUT_DIR}
out=${2:?usage: sbatch --array=0-(N-1) sweep-array.sh SWEEP.toml OUT_DIR}
bin=${PMA_EXO:-pma-exo}
parts=${SLURM_ARRAY_TASK_COUNT:?run me with sbatch --array}
part=$((SLURM_ARRAY_TASK_ID + 1))
# pma-exo creates one directory level (the shard's): the parent is made here.
mkdir -p "$out"
exec "$bin" sweep "$sweep" --out "$out/shard-$SLURM_ARRAY_TASK_ID" \
    --shard "$part/$parts" --threads "${SLURM_CPUS_PER_TASK:-1}" --yes

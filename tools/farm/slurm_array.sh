#!/usr/bin/env bash
# One task of a Slurm job array filtering a batch of dumps (docs/farm.md).
#
#   sbatch --array=0-15 tools/farm/slurm_array.sh 'shots/*.pds' OUTDIR [batch options…]
#   sbatch --dependency=afterany:JOBID --wrap 'pathdensity batch --merge OUTDIR'
#
# Each task takes its own share (--shard I/N, I counted from the array's
# first index, N its task count) and writes OUTDIR/NAME/ per dump and
# OUTDIR/batch-shard-I-of-N.json; a rerun of the array skips what is done.
#SBATCH --job-name=pathdensity
#SBATCH --cpus-per-task=2
#SBATCH --mem=4G
#SBATCH --output=pathdensity-%A_%a.log
# A pre-empted task may be requeued, and its log then keeps every attempt.
#SBATCH --requeue
#SBATCH --open-mode=append
set -euo pipefail
if [ $# -lt 2 ]; then
  echo "usage: sbatch --array=0-N tools/farm/slurm_array.sh DUMPS OUTDIR [batch options]" >&2
  exit 2
fi
: "${SLURM_ARRAY_TASK_ID:?not in a Slurm job array (sbatch --array=…)}"
: "${SLURM_ARRAY_TASK_COUNT:?not in a Slurm job array (sbatch --array=…)}"
dumps=$1 out=$2
shift 2
index=$((SLURM_ARRAY_TASK_ID - ${SLURM_ARRAY_TASK_MIN:-0}))
exec "${PATHDENSITY:-pathdensity}" batch "$dumps" -o "$out" \
  --threads "${SLURM_CPUS_PER_TASK:-0}" \
  --shard "$index/$SLURM_ARRAY_TASK_COUNT" "$@"

#!/bin/bash
# A Slurm array job for `musculo augment`: one array task per shard, then the merge.
#
#   sbatch --array=0-63 examples/slurm_augment.sh /data/HumanML3D/new_joints /shared/augmented
#   # when every task has finished:
#   musculo merge /shared/augmented
#
# (or chain the merge: sbatch --dependency=afterany:<array job id> --wrap "musculo merge OUT").
# The shard split is deterministic, so a failed task can simply be resubmitted with
# `--array=<its index>`; `--resume` makes it skip the clips it had finished.
#SBATCH --job-name=musculo-augment
#SBATCH --cpus-per-task=4
#SBATCH --mem=2G
#SBATCH --time=02:00:00
set -euo pipefail
input=${1:?input folder}
out=${2:?output folder on a shared filesystem}
shards=${SLURM_ARRAY_TASK_COUNT:?run as an array job: sbatch --array=0-N-1}
musculo augment --input "$input" --format humanml3d --out "$out" \
    --shard "$((SLURM_ARRAY_TASK_ID - ${SLURM_ARRAY_TASK_MIN:-0}))/${shards}" --jobs "${SLURM_CPUS_PER_TASK:-1}" --resume

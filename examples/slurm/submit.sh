#!/usr/bin/env bash
# Runs a campaign as a Slurm job array of N shards and a dependent merge job.
#   examples/slurm/submit.sh INPUT.nml OUT.h5 N [CPUS_PER_TASK]
# Set ELLROLL to the ellroll executable if it is not on PATH. Prints the job ids.
set -euo pipefail
if [ $# -lt 3 ]; then
  echo "usage: $0 INPUT.nml OUT.h5 N [CPUS_PER_TASK]" >&2
  exit 2
fi
input=$(realpath "$1")
out=$(realpath -m "$2")
n=$3
cpus=${4:-2}
here=$(dirname "$(realpath "$0")")
"${ELLROLL:-ellroll}" check "$input" -o "$out" > /dev/null     # refuse bad input before queueing
array=$(sbatch --parsable --array="0-$((n - 1))" --cpus-per-task="$cpus" \
        "$here/campaign.sbatch" "$input" "$out")
merge=$(sbatch --parsable --dependency="afterok:${array}" "$here/merge.sbatch" "$out" "$n")
echo "array job $array, merge job $merge"

#!/usr/bin/env bash
# Runs a campaign as a Slurm job array of N shards and a dependent merge job.
#   examples/slurm/submit.sh [--time T] [--mem M] INPUT.nml OUT.h5 N [CPUS_PER_TASK]
# --time and --mem go to each array task (sbatch's formats: --time=2:00:00,
# --mem=4G); a task that reaches its time limit requeues itself and resumes
# (campaign.sbatch). The jobs run the ellroll executable named by ELLROLL,
# else the ellroll on PATH, else the one beside this script (the checkout's
# build/ellroll, or P/bin/ellroll once installed). Prints the job ids.
set -euo pipefail
usage="usage: $0 [--time T] [--mem M] INPUT.nml OUT.h5 N [CPUS_PER_TASK]"
task_options=()
while [ $# -gt 0 ]; do
  case $1 in
    --time | --mem)
      [ $# -ge 2 ] || { echo "$usage" >&2; exit 2; }
      task_options+=("$1=$2")
      shift 2 ;;
    --time=* | --mem=*)
      task_options+=("$1")
      shift ;;
    -*)
      echo "$usage" >&2
      exit 2 ;;
    *)
      break ;;
  esac
done
if [ $# -lt 3 ]; then
  echo "$usage" >&2
  exit 2
fi
input=$(realpath "$1")
out=$(realpath -m "$2")
n=$3
cpus=${4:-2}
here=$(dirname "$(realpath "$0")")
ellroll=${ELLROLL:-$(command -v ellroll || true)}
for candidate in "$here/../../build/ellroll" "$here/../../../../bin/ellroll"; do
  if [ -z "$ellroll" ] && [ -x "$candidate" ]; then
    ellroll=$candidate
  fi
done
if [ -z "$ellroll" ]; then
  echo "$0: no ellroll executable: set ELLROLL, put ellroll on PATH, or build it (build/ellroll)" >&2
  exit 2
fi
if ! found=$(command -v "$ellroll"); then
  echo "$0: $ellroll: no such executable" >&2
  exit 2
fi
ELLROLL=$(realpath "$found")
export ELLROLL                                                # the array and merge jobs run this one
"$ELLROLL" check "$input" -o "$out" > /dev/null               # refuse bad input before queueing
array=$(sbatch --parsable --array="0-$((n - 1))" --cpus-per-task="$cpus" "${task_options[@]}" \
        "$here/campaign.sbatch" "$input" "$out")
# a failed task (a second submission refused by the first one's lock, say)
# cancels the merge instead of leaving it pending forever
merge=$(sbatch --parsable --dependency="afterok:${array}" --kill-on-invalid-dep=yes "$here/merge.sbatch" "$out" "$n")
echo "array job $array, merge job $merge"

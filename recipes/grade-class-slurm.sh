#!/usr/bin/env bash
# Grade a class on a Slurm cluster: an array job of N shards, then a merge that writes the
# class's gradebooks and feedback exactly as one `kalman-course grade` run would.
#
#   bash recipes/grade-class-slurm.sh SUBMISSIONS RELEASE OUT [N]
#
# Writes OUT/grades.csv, OUT/grades.json and OUT/feedback/ (N defaults to 4 shards).
set -euo pipefail
submissions=${1:?usage: grade-class-slurm.sh SUBMISSIONS RELEASE OUT [N]}
release=${2:?usage: grade-class-slurm.sh SUBMISSIONS RELEASE OUT [N]}
out=${3:?usage: grade-class-slurm.sh SUBMISSIONS RELEASE OUT [N]}
n=${4:-4}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
job=$(sbatch --parsable --array="1-$n" "$here/grade-shard.sbatch" "$submissions" "$release" "$out")
sbatch --parsable --dependency="afterok:$job" --job-name=kalman-merge --output="$out/merge.log" \
    --wrap "kalman-course merge $out/shards/shard-*.json --csv $out/grades.csv --json $out/grades.json --feedback $out/feedback; test \$? -le 1"
echo "submitted array job $job ($n shards) and its merge; results in $out"

#!/usr/bin/env bash
# Grade a class on a Slurm cluster: an array job of N shards, then a merge that writes the
# class's gradebooks and feedback exactly as one `kalman-course grade` run would.
#
#   bash recipes/grade-class-slurm.sh SUBMISSIONS RELEASE OUT [N [KEY_FILE [SEED]]]
#
# Writes OUT/grades.csv, OUT/grades.json and OUT/feedback/ (N defaults to 4 shards). Each shard
# is signed and the merge verifies every signature, with the instructor's gradebook key: in
# KEY_FILE (readable only by you: `openssl rand -hex 32 > KEY_FILE; chmod 600 KEY_FILE`), or
# exported as KALMAN_COURSE_GRADEBOOK_KEY before running this (sbatch passes your environment on).
# SEED: the run seed every shard's checks draw their inputs from (default: a fresh one; a
# gradebook's seed grades the class again with the same inputs).
set -euo pipefail
usage="usage: grade-class-slurm.sh SUBMISSIONS RELEASE OUT [N [KEY_FILE [SEED]]]"
submissions=${1:?$usage}
release=${2:?$usage}
out=${3:?$usage}
n=${4:-4}
key_file=${5:-}
seed=${6:-}
if [ -n "$key_file" ]; then
    [ -r "$key_file" ] || { echo "error: cannot read the key file $key_file" >&2; exit 2; }
    key_file=$(cd "$(dirname "$key_file")" && pwd)/$(basename "$key_file")  # tasks may start elsewhere
elif [ -z "${KALMAN_COURSE_GRADEBOOK_KEY:-}" ]; then
    echo "error: no gradebook key: pass KEY_FILE or export KALMAN_COURSE_GRADEBOOK_KEY ($usage)" >&2
    exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
# one run seed for every shard: the whole class's checks draw the same inputs (the gradebook records it)
[ -n "$seed" ] || seed=$(python3 -c 'import secrets; print(secrets.randbits(63))')
mkdir -p "$out"
job=$(sbatch --parsable --array="1-$n" "$here/grade-shard.sbatch" "$submissions" "$release" "$out" "$seed" ${key_file:+"$key_file"})
sbatch --parsable --dependency="afterok:$job" --job-name=kalman-merge --output="$out/merge.log" \
    --wrap "kalman-course merge $out/shards/shard-*.json --csv $out/grades.csv --json $out/grades.json --feedback $out/feedback ${key_file:+--key-file $(printf %q "$key_file")}; test \$? -le 1"
echo "submitted array job $job ($n shards) and its merge; results in $out"

#!/usr/bin/env bash
# Runs `trainer study` on a Slurm cluster: a job array with one shard of the study per array task, and a
# job that waits for the whole array and joins the shards' results with `trainer study merge`.
#
# Usage:
#   scripts/study-slurm.sh CONFIG OUT N [SBATCH_OPTION...]
#     CONFIG  study config JSON (e.g. trainer/study-paper.json), or "default" for the embedded one
#     OUT     output folder: shard I writes OUT/shard-I, the merged REPORT.md / results.json go to OUT
#     N       number of array tasks (shards); job j of the study runs in task j mod N
#     SBATCH_OPTION...  passed to both sbatch calls, e.g. --partition=cpu --time=04:00:00 --account=X
#
#   Environment:
#     TRAINER        the trainer binary (default target/release/trainer; build it with
#                    `cargo build --release -p trainer` first), made absolute before submitting
#     CPUS           CPUs per array task (default 2)
#     NBRDF_DATA     shared data folder (meshes, MERL fits, LPIPS weights), passed through to the jobs
#
#   Example: 16 tasks of the paper-scale config, then the merge:
#     scripts/study-slurm.sh trainer/study-paper.json /scratch/$USER/paper 16 --time=12:00:00
#
# It prints the two job ids. Each shard keeps its finished jobs (result.json with the same job hash), so
# resubmitting the same command after a failed or timed-out task reruns only what is missing. The merge
# runs only if every array task succeeded (afterok); to merge by hand:
#   $TRAINER study --out OUT merge OUT/shard-0 … OUT/shard-(N-1)
# Logs: OUT/slurm/shard-I.log and OUT/slurm/merge.log.
#
# The script submits itself: inside the array it is called as `study-slurm.sh __shard CONFIG OUT N`,
# for the merge as `study-slurm.sh __merge OUT N`.
set -euo pipefail

trainer=${TRAINER:-target/release/trainer}

case "${1-}" in
__shard)
    config=$2 out=$3 n=$4
    i=${SLURM_ARRAY_TASK_ID:?"__shard runs inside a Slurm array task"}
    args=(study --out "$out/shard-$i" --shard "$i/$n")
    [ "$config" = default ] || args+=(--config "$config")
    exec "$trainer" "${args[@]}"
    ;;
__merge)
    out=$2 n=$3
    dirs=()
    for ((i = 0; i < n; i++)); do dirs+=("$out/shard-$i"); done
    exec "$trainer" study --out "$out" merge "${dirs[@]}"
    ;;
esac

if [ $# -lt 3 ]; then
    sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//' >&2
    exit 2
fi
config=$1 out=$2 n=$3
shift 3
if ! [[ $n =~ ^[1-9][0-9]*$ ]]; then
    echo "study-slurm.sh: N must be a positive integer, got '$n'" >&2
    exit 2
fi
if [ "$config" != default ]; then
    [ -f "$config" ] || { echo "study-slurm.sh: config $config not found" >&2; exit 2; }
    config=$(realpath "$config")
fi
[ -x "$trainer" ] || { echo "study-slurm.sh: trainer binary $trainer not found (cargo build --release -p trainer, or set TRAINER)" >&2; exit 2; }
command -v sbatch >/dev/null || { echo "study-slurm.sh: sbatch not found: not on a Slurm submit host" >&2; exit 2; }
export TRAINER=$(realpath "$trainer")
mkdir -p "$out/slurm"
out=$(realpath "$out")
self=$(realpath "$0")

array=$(sbatch --parsable --export=ALL --job-name=nbrdf-study --array="0-$((n - 1))" \
    --cpus-per-task="${CPUS:-2}" --output="$out/slurm/shard-%a.log" "$@" \
    "$self" __shard "$config" "$out" "$n")
array=${array%%;*} # --parsable prints "id" or "id;cluster"
merge=$(sbatch --parsable --export=ALL --job-name=nbrdf-study-merge --dependency="afterok:$array" \
    --cpus-per-task=1 --output="$out/slurm/merge.log" "$@" \
    "$self" __merge "$out" "$n")
echo "array job $array ($n shards into $out/shard-*), merge job ${merge%%;*} (report in $out)"

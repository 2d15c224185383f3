#!/bin/bash
# All-pairs cP distance matrix of a large library as a Slurm job array.
# Run it on a login node; docs/slurm.md explains each step.
#
#   bash slurm-matrix.sh                      submit the array and the merge job
#   bash slurm-matrix.sh resubmit OUTDIR K…   run tasks K… again and re-point the merge
#   bash slurm-matrix.sh merge OUTDIR         merge by hand (here, not as a job)
#
# Settings come from the environment when submitting (defaults in brackets):
#   LIBRARY   [library]      folder of surfaces (labels.csv + meshes)
#   OUTDIR    [shards]       shard files, logs and the submission record
#   MATRIX    [matrix.csv]   the merged matrix
#   SHARDS    [16]           number of array tasks
#   CPUS      [the smallest node's CPU count in the partition, at most 8]
#   MEM       [4G]           memory per task
#   TIME      [04:00:00]     time limit per task
#   PARTITION [the cluster's default]
#   MORPHOID  [morphoid from PATH]
#   CACHE     []             the cache `morphoid library build` printed (optional)
#   CONFIG    []             the configuration of that build (optional)
# Relative paths are taken from the folder you submit from. Everything is
# written to OUTDIR/submission.env at submission, and the tasks, the merge
# job and `resubmit` read it from there: nothing needs to stay exported.

set -euo pipefail

script=$(realpath "${BASH_SOURCE[0]}")

# Load the submission record of OUTDIR (given as the first argument).
load() {
    local env="${1:?give the OUTDIR of the submission}/submission.env"
    [[ -f "$env" ]] || { echo "no submission record $env" >&2; exit 1; }
    # shellcheck source=/dev/null
    source "$env"
}

# sbatch options common to every job of the submission.
common() {
    opts=(--parsable)
    [[ -n "$PARTITION" ]] && opts+=(--partition="$PARTITION")
    return 0
}

# Submit array tasks ($1: the --array list) and return the job id.
submit_tasks() {
    common
    # --output is given here, not as #SBATCH: only here is OUTDIR known.
    sbatch "${opts[@]}" --job-name=morphoid-matrix --array="$1" \
        --cpus-per-task="$CPUS" --mem="$MEM" --time="$TIME" \
        --output="$OUTDIR/task-%A_%a.log" \
        "$script" task "$OUTDIR"
}

# Submit the merge job after $1 (a --dependency list); record its id.
submit_merge() {
    common
    local id
    id=$(sbatch "${opts[@]}" --job-name=morphoid-merge --dependency="$1" \
        --kill-on-invalid-dep=yes --cpus-per-task=1 --mem=2G --time=00:30:00 \
        --output="$OUTDIR/merge-%j.log" "$script" merge "$OUTDIR")
    printf 'MERGE_JOB=%q\n' "$id" >>"$OUTDIR/submission.env"
    echo "$id"
}

merge() {
    exec "$MORPHOID" matrix merge "$OUTDIR"/shard-*-of-"$SHARDS".csv --out "$MATRIX"
}

mode=${1:-submit}
case "$mode" in
submit)
    SHARDS=${SHARDS:-16}
    LIBRARY=$(realpath -m "${LIBRARY:-library}")
    OUTDIR=$(realpath -m "${OUTDIR:-shards}")
    MATRIX=$(realpath -m "${MATRIX:-matrix.csv}")
    MORPHOID=$(realpath -m "$(command -v "${MORPHOID:-morphoid}" || echo "${MORPHOID:-morphoid}")")
    CACHE=${CACHE:+$(realpath -m "$CACHE")}
    CONFIG=${CONFIG:+$(realpath -m "$CONFIG")}
    PARTITION=${PARTITION:-}
    MEM=${MEM:-4G}
    TIME=${TIME:-04:00:00}
    if [[ -z "${CPUS:-}" ]]; then
        # A task asking for more CPUs than a node has stays pending forever.
        CPUS=$(sinfo -h ${PARTITION:+--partition="$PARTITION"} -o '%c' | sort -n | head -n 1)
        CPUS=$((CPUS > 8 ? 8 : CPUS))
    fi
    [[ -x "$MORPHOID" ]] || { echo "MORPHOID: no executable $MORPHOID" >&2; exit 1; }
    [[ -d "$LIBRARY" ]] || { echo "LIBRARY: no folder $LIBRARY" >&2; exit 1; }
    if compgen -G "$OUTDIR/shard-*.csv" >/dev/null; then
        echo "$OUTDIR already holds shards: use another OUTDIR, or resubmit" >&2
        exit 1
    fi
    mkdir -p "$OUTDIR"
    for v in SHARDS LIBRARY OUTDIR MATRIX MORPHOID CACHE CONFIG PARTITION CPUS MEM TIME; do
        printf '%s=%q\n' "$v" "${!v}"
    done >"$OUTDIR/submission.env"
    array=$(submit_tasks "1-$SHARDS")
    printf 'ARRAY_JOBS=%q\n' "$array" >>"$OUTDIR/submission.env"
    merge_id=$(submit_merge "afterok:$array")
    echo "submitted array $array ($SHARDS shards, $CPUS CPUs each) and merge $merge_id; record $OUTDIR/submission.env"
    ;;
resubmit)
    load "${2:-}"
    shift 2
    (($# > 0)) || { echo "give the task numbers to run again" >&2; exit 1; }
    # The old merge job waits for an array with a failed task: it would
    # never start (or was already cancelled); replace it.
    scancel "$MERGE_JOB" 2>/dev/null || true
    again=$(IFS=,; echo "$*")
    # A shard file is written whole or not at all; an older one goes so
    # that only the new run's can be merged.
    for k in "$@"; do rm -f "$OUTDIR/shard-$k-of-$SHARDS.csv"; done
    array=$(submit_tasks "$again")
    # After every earlier array has ended (whatever its outcome) and the
    # new tasks succeeded.
    after="afterok:$array"
    for job in $ARRAY_JOBS; do after="afterany:$job,$after"; done
    printf 'ARRAY_JOBS=%q\n' "$ARRAY_JOBS $array" >>"$OUTDIR/submission.env"
    merge_id=$(submit_merge "$after")
    echo "resubmitted task(s) $again as $array; merge $merge_id replaces the old one"
    ;;
task)
    load "${2:-}"
    args=(matrix --library "$LIBRARY"
        --shard "${SLURM_ARRAY_TASK_ID:?not inside a Slurm array task}/$SHARDS"
        --threads "${SLURM_CPUS_PER_TASK:-1}"
        --out "$OUTDIR/shard-${SLURM_ARRAY_TASK_ID}-of-$SHARDS.csv")
    [[ -n "$CACHE" ]] && args+=(--cache "$CACHE")
    [[ -n "$CONFIG" ]] && args+=(--config "$CONFIG")
    exec "$MORPHOID" "${args[@]}"
    ;;
merge)
    load "${2:-}"
    merge
    ;;
*)
    echo "usage: slurm-matrix.sh [submit | resubmit OUTDIR K… | merge OUTDIR]" >&2
    exit 2
    ;;
esac

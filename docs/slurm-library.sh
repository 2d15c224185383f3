#!/bin/bash
# A large reference library prepared and calibrated as Slurm job arrays.
# Run it on a login node; docs/slurm.md explains each step.
#
#   bash slurm-library.sh                      submit the arrays and the merge job
#   bash slurm-library.sh resubmit OUTDIR K…   run calibration tasks K… again and re-point the merge
#   bash slurm-library.sh merge OUTDIR         merge by hand (here, not as a job)
#
# Settings come from the environment when submitting (defaults in brackets):
#   CONFIG    (required)     the configuration: [library] dir, cache (on
#                            storage every node sees), calibrate = true
#   LIBRARY   [the configuration's]  folder of surfaces (labels.csv + meshes)
#   OUTDIR    [library-build] calibration shards, logs and the submission record
#   SHARDS    [16]           number of tasks of each array
#   CPUS      [the smallest node's CPU count in the partition, at most 8]
#   MEM       [4G]           memory per task
#   TIME      [04:00:00]     time limit per task
#   PARTITION [the cluster's default]
#   MORPHOID  [morphoid from PATH]
# Relative paths are taken from the folder you submit from. Everything is
# written to OUTDIR/submission.env at submission, and the tasks, the merge
# job and `resubmit` read it from there: nothing needs to stay exported.
#
# Three steps: array 1 prepares part K of the references into the shared
# cache (`library build --shard K/N`); array 2, once array 1 has ended
# whatever its outcome, computes part K of the calibration's comparisons
# (`library calibrate --shard K/N`; a reference array 1 failed to prepare
# is prepared there); the merge job stores the calibration in the cache
# (`library calibrate merge`), byte for byte what one machine stores.

set -euo pipefail

script=$(realpath "${BASH_SOURCE[0]}")

load() {
    local env="${1:?give the OUTDIR of the submission}/submission.env"
    [[ -f "$env" ]] || { echo "no submission record $env" >&2; exit 1; }
    # shellcheck source=/dev/null
    source "$env"
}

common() {
    opts=(--parsable)
    [[ -n "$PARTITION" ]] && opts+=(--partition="$PARTITION")
    return 0
}

# Submit array tasks of step $1 (prepare | calibrate) for the --array
# list $2, after the --dependency list $3 (may be empty); print the job id.
submit_tasks() {
    common
    [[ -n "$3" ]] && opts+=(--dependency="$3")
    sbatch "${opts[@]}" --job-name="morphoid-$1" --array="$2" \
        --cpus-per-task="$CPUS" --mem="$MEM" --time="$TIME" \
        --output="$OUTDIR/$1-%A_%a.log" \
        "$script" "$1" "$OUTDIR"
}

submit_merge() {
    common
    local id
    id=$(sbatch "${opts[@]}" --job-name=morphoid-calibration-merge --dependency="$1" \
        --kill-on-invalid-dep=yes --cpus-per-task="$CPUS" --mem="$MEM" --time="$TIME" \
        --output="$OUTDIR/merge-%j.log" "$script" merge "$OUTDIR")
    printf 'MERGE_JOB=%q\n' "$id" >>"$OUTDIR/submission.env"
    echo "$id"
}

# The morphoid command line common to every step.
morphoid_args() {
    args=(--config "$CONFIG")
}

library_args() {
    [[ -n "$LIBRARY" ]] && args+=(--library "$LIBRARY")
    return 0
}

task_shard() {
    echo "${SLURM_ARRAY_TASK_ID:?not inside a Slurm array task}/$SHARDS"
}

mode=${1:-submit}
case "$mode" in
submit)
    [[ -n "${CONFIG:-}" ]] || { echo "CONFIG: give the configuration of the library" >&2; exit 1; }
    CONFIG=$(realpath -m "$CONFIG")
    [[ -f "$CONFIG" ]] || { echo "CONFIG: no file $CONFIG" >&2; exit 1; }
    SHARDS=${SHARDS:-16}
    LIBRARY=${LIBRARY:+$(realpath -m "$LIBRARY")}
    OUTDIR=$(realpath -m "${OUTDIR:-library-build}")
    MORPHOID=$(realpath -m "$(command -v "${MORPHOID:-morphoid}" || echo "${MORPHOID:-morphoid}")")
    PARTITION=${PARTITION:-}
    MEM=${MEM:-4G}
    TIME=${TIME:-04:00:00}
    if [[ -z "${CPUS:-}" ]]; then
        # A task asking for more CPUs than a node has stays pending forever.
        CPUS=$(sinfo -h ${PARTITION:+--partition="$PARTITION"} -o '%c' | sort -n | head -n 1)
        CPUS=$((CPUS > 8 ? 8 : CPUS))
    fi
    [[ -x "$MORPHOID" ]] || { echo "MORPHOID: no executable $MORPHOID" >&2; exit 1; }
    if compgen -G "$OUTDIR/calibration-*.bin" >/dev/null; then
        echo "$OUTDIR already holds calibration shards: use another OUTDIR, or resubmit" >&2
        exit 1
    fi
    mkdir -p "$OUTDIR"
    for v in SHARDS CONFIG LIBRARY OUTDIR MORPHOID PARTITION CPUS MEM TIME; do
        printf '%s=%q\n' "$v" "${!v}"
    done >"$OUTDIR/submission.env"
    prepare=$(submit_tasks prepare "1-$SHARDS" "")
    calibrate=$(submit_tasks calibrate "1-$SHARDS" "afterany:$prepare")
    printf 'ARRAY_JOBS=%q\n' "$calibrate" >>"$OUTDIR/submission.env"
    merge_id=$(submit_merge "afterok:$calibrate")
    echo "submitted preparation array $prepare, calibration array $calibrate ($SHARDS tasks, $CPUS CPUs each) and merge $merge_id; record $OUTDIR/submission.env"
    ;;
resubmit)
    load "${2:-}"
    shift 2
    (($# > 0)) || { echo "give the calibration task numbers to run again" >&2; exit 1; }
    scancel "$MERGE_JOB" 2>/dev/null || true
    again=$(IFS=,; echo "$*")
    for k in "$@"; do rm -f "$OUTDIR/calibration-$k-of-$SHARDS.bin"; done
    array=$(submit_tasks calibrate "$again" "")
    after="afterok:$array"
    for job in $ARRAY_JOBS; do after="afterany:$job,$after"; done
    printf 'ARRAY_JOBS=%q\n' "$ARRAY_JOBS $array" >>"$OUTDIR/submission.env"
    merge_id=$(submit_merge "$after")
    echo "resubmitted calibration task(s) $again as $array; merge $merge_id replaces the old one"
    ;;
prepare)
    load "${2:-}"
    morphoid_args
    args+=(library build --shard "$(task_shard)")
    library_args
    RAYON_NUM_THREADS="${SLURM_CPUS_PER_TASK:-1}" exec "$MORPHOID" "${args[@]}"
    ;;
calibrate)
    load "${2:-}"
    morphoid_args
    args+=(library calibrate --shard "$(task_shard)"
        --out "$OUTDIR/calibration-${SLURM_ARRAY_TASK_ID}-of-$SHARDS.bin")
    library_args
    RAYON_NUM_THREADS="${SLURM_CPUS_PER_TASK:-1}" exec "$MORPHOID" "${args[@]}"
    ;;
merge)
    load "${2:-}"
    morphoid_args
    args+=(library calibrate merge)
    library_args
    exec "$MORPHOID" "${args[@]}" "$OUTDIR"/calibration-*-of-"$SHARDS".bin
    ;;
*)
    echo "usage: slurm-library.sh [submit | resubmit OUTDIR K… | merge OUTDIR]" >&2
    exit 2
    ;;
esac

#!/bin/bash
# All-pairs cP distance matrix of a large library as a Slurm job array.
#
# Submit from a login node (from the folder that holds the library):
#
#     bash slurm-matrix.sh            # submits the array and the merge job
#
# Each array task computes one shard (a contiguous part of the sorted pair
# list) with `morphoid matrix --shard K/N`; a merge job that starts only
# when every task succeeded (afterok) checks the shards and writes the full
# matrix. Adjust the variables and the #SBATCH lines to your cluster.
#
#SBATCH --job-name=morphoid-matrix
#SBATCH --array=1-16
#SBATCH --cpus-per-task=8
#SBATCH --mem=4G
#SBATCH --time=04:00:00
#SBATCH --output=shards/matrix-%A_%a.log

set -euo pipefail

SHARDS=16                          # must equal the N of `--array=1-N` above
LIBRARY=${LIBRARY:-library}        # labels.csv + meshes
OUTDIR=${OUTDIR:-shards}           # shard files and logs
MATRIX=${MATRIX:-matrix.csv}       # the merged result
MORPHOID=${MORPHOID:-morphoid}     # path to the binary
CACHE=${CACHE:-}                   # optional: the cache folder of
                                   # `morphoid library build` (run it first)
CONFIG=${CONFIG:-}                 # optional: the configuration of that build

if [[ -z "${SLURM_ARRAY_TASK_ID:-}" ]]; then
    # Not inside the array: submit it, then the merge job that depends on it.
    mkdir -p "$OUTDIR"
    array_id=$(sbatch --parsable --array="1-${SHARDS}" "$0")
    merge_id=$(sbatch --parsable --job-name=morphoid-merge \
        --dependency="afterok:${array_id}" --cpus-per-task=1 --mem=2G \
        --time=00:30:00 --output="${OUTDIR}/merge-%j.log" \
        --wrap="${MORPHOID} matrix merge ${OUTDIR}/shard-*-of-${SHARDS}.csv --out ${MATRIX}")
    echo "submitted array ${array_id} (${SHARDS} shards) and merge ${merge_id}"
    exit 0
fi

# One shard: prepares only the specimens its pairs involve (or loads them
# from the cache), compares its pairs on all the task's cores.
cache_args=()
if [[ -n "$CACHE" ]]; then
    cache_args=(--cache "$CACHE")
fi
if [[ -n "$CONFIG" ]]; then
    cache_args+=(--config "$CONFIG")
fi
exec "$MORPHOID" matrix \
    --library "$LIBRARY" \
    ${cache_args[@]+"${cache_args[@]}"} \
    --shard "${SLURM_ARRAY_TASK_ID}/${SHARDS}" \
    --threads "${SLURM_CPUS_PER_TASK:-1}" \
    --out "${OUTDIR}/shard-${SLURM_ARRAY_TASK_ID}-of-${SHARDS}.csv"

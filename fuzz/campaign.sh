#!/usr/bin/env bash
# A fuzz campaign over every target (or the targets named): the seeds
# written from the synthetic data, the targets built with cargo-fuzz on
# the nightly toolchain, then each target run for SECONDS (three times as
# long for the readers of files that arrive from outside: meshes, slices,
# DICOM, NRRD, NIfTI), two at a time at the lowest priority. Crashes,
# hangs and huge allocations do not stop a target (libFuzzer's fork mode);
# they are saved under fuzz/artifacts/<target>/. The summary gives, per
# target, the executions, libFuzzer's coverage (cov, ft) and what it found.
#
#   fuzz/campaign.sh [SECONDS] [TARGET…]     (SECONDS: 300 unless given)
set -euo pipefail
cd "$(dirname "$0")"

seconds=${1:-300}
shift || true
external="ply obj stl off tiff png bmp dicom nrrd nifti"
all="$external tps morphologika fcsv mrk_json pp config labels matrix shard clean volume_pipeline"
targets=${*:-$all}

if [ ! -d seeds ]; then
    (cd .. && nice -n 10 cargo run --release --example fuzz_seeds -- fuzz/seeds)
fi
# Built once, then the binaries are run: a commit would otherwise make
# each `cargo fuzz run` rebuild the crate (build.rs records the commit).
export MORPHOID_COMMIT=${MORPHOID_COMMIT:-fuzz}
nice -n 10 cargo +nightly fuzz build --codegen-units 16
export bin=target/x86_64-unknown-linux-gnu/release
mkdir -p logs

run_one() {
    local target=$1 time=$2
    mkdir -p "corpus/$target" "artifacts/$target" "seeds/$target"
    # Limits: 10 s per input is a hang, 1 GB (resident or one allocation)
    # too much, inputs up to 1 MB.
    nice -n 19 "$bin/$target" "corpus/$target" "seeds/$target" \
        -artifact_prefix="artifacts/$target/" \
        -max_total_time="$time" -rss_limit_mb=1024 -malloc_limit_mb=1024 \
        -timeout=10 -max_len=1048576 -fork=1 -ignore_crashes=1 \
        -ignore_timeouts=1 -ignore_ooms=1 -print_final_stats=1 \
        >"logs/$target.log" 2>&1 || true
}
export -f run_one

for t in $targets; do
    case " $external " in
    *" $t "*) echo "$t $((3 * seconds))" ;;
    *) echo "$t $seconds" ;;
    esac
done | xargs -P 2 -L 1 bash -c 'run_one "$0" "$1"'

printf '%-16s %12s %8s %8s %8s %6s\n' target executions cov ft seconds found
for t in $targets; do
    log="logs/$t.log"
    # Fork mode's progress lines: "#EXECS: cov: C ft: F corp: … time: Ts".
    last=$(grep -E '^#[0-9]+: cov: ' "$log" | tail -n 1 || true)
    execs=$(sed -E 's/^#([0-9]+):.*/\1/' <<<"$last")
    cov=$(sed -E 's/.* cov: ([0-9]+).*/\1/' <<<"$last")
    ft=$(sed -E 's/.* ft: ([0-9]+).*/\1/' <<<"$last")
    secs=$(sed -E 's/.* time: ([0-9]+)s.*/\1/' <<<"$last")
    found=$(find "artifacts/$t" -type f | wc -l)
    printf '%-16s %12s %8s %8s %8s %6s\n' "$t" "$execs" "$cov" "$ft" "$secs" "$found"
done

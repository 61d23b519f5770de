#!/usr/bin/env bash
# Runs every fuzz target (or those in $TARGETS) at once for SECONDS, each with WORKERS libFuzzer processes
# (-fork), growing the corpus in CORPUS/<target> from fuzz/seeds/<target>, and keeps
# going past crashes, timeouts and out-of-memory inputs so one run finds them all.
# Artifacts (the inputs that failed) land in OUT/artifacts/; logs in OUT/<target>.log.
#   fuzz/run.sh BIN_DIR SECONDS WORKERS CORPUS OUT
# BIN_DIR holds the binaries `cargo +nightly fuzz build -O` makes (docs/fuzz.md).
set -euo pipefail
bin=$1 seconds=$2 workers=$3 corpus=$4 out=$5
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out/artifacts"
for t in ${TARGETS:-obj scene image xml ply replot}; do
    mkdir -p "$corpus/$t"
    # 10 s per input at most; 2 GiB of memory at most (one allocation included): a
    # loader that reads without a bound trips it.
    "$bin/$t" "$corpus/$t" "$here/seeds/$t" -fork="$workers" -max_total_time="$seconds" \
        -timeout=10 -rss_limit_mb=2048 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 \
        -artifact_prefix="$out/artifacts/$t-" > "$out/$t.log" 2>&1 &
done
wait
for t in ${TARGETS:-obj scene image xml ply replot}; do
    echo "== $t: $(ls "$corpus/$t" | wc -l) corpus inputs"
    grep -E "^#[0-9]+: cov" "$out/$t.log" | tail -1 || true
    grep -cE "^==[0-9]+== ERROR|panicked at|deadly signal|Timeout|out-of-memory" "$out/$t.log" || true
done
ls -la "$out/artifacts"

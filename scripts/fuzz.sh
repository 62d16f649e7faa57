#!/usr/bin/env bash
# The long fuzzing run: the same targets as `cargo test --test fuzz`, with many more cases, larger inputs
# (whole logs, megabyte lines), in release, and a summary of inputs tried and findings per target.
#
#   scripts/fuzz.sh                 # FUZZ_CASES=100x (100 times each target's test-suite count)
#   FUZZ_CASES=200000 scripts/fuzz.sh
#   FUZZ_SECONDS=120 scripts/fuzz.sh            # at most 2 minutes per target
#   FUZZ_SEED=c0ffee scripts/fuzz.sh nmea       # another seed; only tests whose name contains "nmea"
#   FUZZ_REPLAY=nmea:1a2b3c scripts/fuzz.sh     # rerun one case (seed printed with every finding)
#
# Findings are minimised and saved under target/tmp/fuzz-findings/. Exit status is cargo's: non-zero when
# a target found something new.
set -euo pipefail
cd "$(dirname "$0")/.."

export FUZZ_CASES="${FUZZ_CASES:-100x}"
export FUZZ_SEED="${FUZZ_SEED:-$(printf '%x' "$(date +%s)")}"
# Release is ~10x faster than the test suite's debug build; keep per-input limits tight accordingly.
export FUZZ_TIME_FACTOR="${FUZZ_TIME_FACTOR:-1}"
filter="${1:-}"

log="target/tmp/fuzz-$(date -u +%Y%m%dT%H%M%SZ).log"
mkdir -p target/tmp
echo "fuzz: FUZZ_CASES=$FUZZ_CASES FUZZ_SEED=$FUZZ_SEED ${FUZZ_SECONDS:+FUZZ_SECONDS=$FUZZ_SECONDS }log $log"
start=$(date +%s)
status=0
# One test at a time: each target gets both cores' worth of the machine and its own timing.
cargo test --release --test fuzz -- --nocapture --test-threads=1 ${filter:+"$filter"} 2>&1 | tee "$log" || status=$?
end=$(date +%s)

echo
echo "==== fuzz summary (seed $FUZZ_SEED, $((end - start)) s wall) ===="
# With --nocapture a summary can follow the "test name ... " prefix on the same line.
sed -E 's/^test .* \.\.\. (FUZZ-SUMMARY)/\1/' "$log" |
    grep -E "^FUZZ-SUMMARY|^    [a-z ]+: [0-9]+$|^  (NEW|KNOWN)|^    (first|minimised|known issue)|FAILED|^test result|FUZZ HANG" |
    cut -c1-400 || true
exit "$status"

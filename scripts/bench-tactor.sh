#!/usr/bin/env sh
# Tactor model benchmarks: criterion (one 10 s simulation, a 40-point sweep), then the scipy peer comparison.
set -eu
cd "$(dirname "$0")/.."
cargo bench -p vestnav-core --bench tactor
cargo build --release --bin vestnav
python3 scripts/bench-tactor-vs-scipy.py "$@"

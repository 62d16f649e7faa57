#!/usr/bin/env bash
# What CI does: formatting, lints as errors, docs, the firmware in the loop, and the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."

cargo fmt --all --check
cargo clippy --workspace --all-targets --locked -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked --quiet
# The firmware, its harness and the WTCU conformance suite against the emulator and the firmware.
scripts/hil.sh
VESTNAV_HIL_SKIP=1 cargo test --workspace --locked

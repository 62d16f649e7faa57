#!/usr/bin/env bash
# Hardware in the loop without hardware: builds the reference WTCU firmware (firmware/, avr-gcc) and the
# simavr harness (firmware/sim/), runs the firmware's host test (the protocol core against the
# document's test vectors), then the WTCU conformance suite (tests/hil) against the Rust emulator and
# both firmware images running in simavr. Prints "N passed, M failed" for each stage.
#
# Needs: gcc-avr avr-libc simavr libsimavr-dev libelf-dev (Debian), a host C compiler.
set -euo pipefail
cd "$(dirname "$0")/.."

make -s -C firmware all
make -s -C firmware size
make -s -C firmware/sim
make -s -C firmware host-test
VESTNAV_HIL_REQUIRE_FIRMWARE=1 cargo test --locked --test hil -- "$@"

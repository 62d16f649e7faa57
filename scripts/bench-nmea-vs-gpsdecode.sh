#!/usr/bin/env sh
# NMEA decode throughput: `vestnav nmea decode --json` against gpsd's `gpsdecode` (gpsd-tools) on the same
# input, in one run. Input: the gpsd regression logs (tests/data/gpsd-logs/*.log) concatenated REPEAT times
# (default 20, ~66 MB). Both tools read the file and write one JSON report per epoch to /dev/null.
# Prints MB/s of each and the ratio (goal: >= 5x gpsdecode). Usage: scripts/bench-nmea-vs-gpsdecode.sh [REPEAT]
set -eu
cd "$(dirname "$0")/.."
REPEAT="${1:-20}"
command -v gpsdecode >/dev/null 2>&1 || { echo "gpsdecode not found: apt-get install gpsd-clients (or gpsd-tools)"; exit 1; }
cargo build --release --bin vestnav >/dev/null 2>&1 || cargo build --release --bin vestnav
BIN=target/release/vestnav
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
i=0
while [ "$i" -lt "$REPEAT" ]; do cat tests/data/gpsd-logs/*.log >> "$TMP/all.nmea"; i=$((i + 1)); done
BYTES=$(wc -c < "$TMP/all.nmea")

# Time both tools in one Python process (best of 3 wall-clock runs each, output to /dev/null), so no shell or
# interpreter start-up is counted against either side.
TIMES=$(python3 - "$BIN" "$TMP/all.nmea" <<'PY'
import subprocess, sys, time
bin_, path = sys.argv[1], sys.argv[2]
def best(argv, stdin_path="/dev/null"):
    b = None
    for _ in range(3):
        with open(stdin_path, "rb") as inp:
            t0 = time.perf_counter()
            subprocess.run(argv, stdin=inp, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
            d = time.perf_counter() - t0
        b = d if b is None or d < b else b
    return b
print(best([bin_, "nmea", "decode", "--json", path]), best(["gpsdecode"], path))
PY
)
T_OURS=${TIMES% *}
T_GPSD=${TIMES#* }
EPOCHS_OURS=$($BIN nmea decode --json "$TMP/all.nmea" 2>/dev/null | wc -l)
TPV_GPSD=$(gpsdecode < "$TMP/all.nmea" 2>/dev/null | grep -c '"class":"TPV"' || true)
python3 - "$BYTES" "$T_OURS" "$T_GPSD" "$EPOCHS_OURS" "$TPV_GPSD" <<'PY'
import sys
b, to, tg, eo, eg = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3]), sys.argv[4], sys.argv[5]
print(f"input: {b/1e6:.1f} MB (gpsd regression logs x repeat)")
print(f"vestnav nmea decode --json: {to:.3f} s  {b/1e6/to:8.1f} MB/s  ({eo} epochs)")
print(f"gpsdecode:                  {tg:.3f} s  {b/1e6/tg:8.1f} MB/s  ({eg} TPV reports)")
print(f"ratio (gpsdecode time / ours): {tg/to:.1f}x  (goal >= 5x)")
PY

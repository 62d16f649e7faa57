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

now() { python3 -c 'import time; print(time.perf_counter())'; }
best() { # best of 3 wall-clock seconds of "$@"
  b=""
  for _ in 1 2 3; do
    t0=$(now); "$@" > /dev/null 2>&1; t1=$(now)
    b=$(python3 -c "a='$b'; d=$t1-$t0; print(d if a=='' or d<float(a) else a)")
  done
  echo "$b"
}
T_OURS=$(best sh -c "$BIN nmea decode --json '$TMP/all.nmea'")
T_GPSD=$(best sh -c "gpsdecode < '$TMP/all.nmea'")
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

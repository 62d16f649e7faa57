#!/usr/bin/env bash
# The whole gpsd regression suite against our decoder: a measurement, not part of `cargo test` (it needs the
# network once). Downloads Debian's orig tarball of gpsd 3.27.5 (SHA-256 pinned below; cached under
# $XDG_CACHE_HOME/vestnav, else target/gpsd-suite), extracts test/daemon/ (191 logs, each with gpsd's own
# decoded output, .chk; BSD-2, the tarball's COPYING), and runs the ignored test `gpsd_suite` over every log.
# Prints per log and per receiver family gpsd's epochs with a position, ours at the same time, identical
# (time, mode, lat/lon within 1e-7 deg), the whole-suite share, and the logs that give no fix with the
# decoder's reason.
#
#   scripts/gpsd-suite.sh                  # download (once), extract, run
#   scripts/gpsd-suite.sh /path/to/daemon  # an already extracted test/daemon folder (or any folder of logs)
#   VESTNAV_GPSD_SUITE_ONLY=ublox VESTNAV_GPSD_SUITE_MISSES=50 scripts/gpsd-suite.sh   # some logs, more misses
set -euo pipefail
cd "$(dirname "$0")/.."

URL="http://deb.debian.org/debian/pool/main/g/gpsd/gpsd_3.27.5.orig.tar.xz"
SHA256="dc4a62bad835282bae788772bc7cc8f8bec4c7a48e8dceeb37477a89091c4656"

if [ $# -ge 1 ]; then
    DIR="$1"
else
    CACHE="${XDG_CACHE_HOME:+$XDG_CACHE_HOME/vestnav}"
    CACHE="${CACHE:-target/gpsd-suite}"
    mkdir -p "$CACHE"
    TAR="$CACHE/gpsd_3.27.5.orig.tar.xz"
    if ! echo "$SHA256  $TAR" | sha256sum -c --status 2>/dev/null; then
        echo "downloading $URL" >&2
        curl -fsSL --retry 3 -o "$TAR.part" "$URL"
        mv "$TAR.part" "$TAR"
    fi
    # Over plain HTTP the pinned hash is the authentication: refuse anything else.
    echo "$SHA256  $TAR" | sha256sum -c --status || { echo "$TAR: SHA-256 mismatch, refusing it" >&2; exit 1; }
    DIR="$CACHE/gpsd-3.27.5/test/daemon"
    if [ ! -d "$DIR" ]; then
        tar -xJf "$TAR" -C "$CACHE" gpsd-3.27.5/test/daemon gpsd-3.27.5/COPYING
    fi
fi
[ -d "$DIR" ] || { echo "$DIR: not a folder" >&2; exit 1; }
DIR="$(cd "$DIR" && pwd)"
VESTNAV_GPSD_SUITE="$DIR" cargo test -q -p vestnav-device --lib gps::truth_tests::suite::gpsd_suite \
    -- --ignored --exact --nocapture

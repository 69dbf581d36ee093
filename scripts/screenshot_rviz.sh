#!/usr/bin/env bash
# Loads rviz/osm_graph_slam.rviz in rviz under a private Xvfb and a private ROS master and writes
# a PNG of the screen. Exits non-zero when rviz dies, reports a configuration/plugin error, or the
# screenshot is blank.
#   scripts/screenshot_rviz.sh [--out FILE.png] [--config FILE.rviz] [--wait SEC] [--bag FILE.bag]
#                              [--launch "PKG FILE.launch ARG:=VALUE ..."]
#   --launch: run roslaunch with these arguments on the private master first (source the
#          workspace's devel/setup.bash before), e.g. a whole SLAM run to look at:
#          --launch "osm_graph_slam sim.launch osm_file:=/tmp/sim/prior.osm bag:=/tmp/sim/drive.bag"
#   --bag: play a bag (rosbag play --clock) on the private master while rviz runs; without it
#          rviz shows the empty views (fixed frame 'map' absent: "Global Status: Warn").
# Only the processes this script starts are stopped (by their ids). Needs Xvfb (xvfb),
# rviz, roscore and python3-pil (pulled in by python3-matplotlib): no x11-apps/imagemagick; the
# frame buffer is read from Xvfb's -fbdir XWD file.
export PATH=/usr/bin:/bin:$PATH  # pyenv's python3 breaks the ROS tools
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="$ROOT/build_ws/rviz_screenshot.png"  # build_ws/ is not committed
CONFIG="$ROOT/rviz/osm_graph_slam.rviz"
WAIT=12
BAG=""
LAUNCH=""
while (($#)); do
  case "$1" in
    --out) OUT="$2"; shift 2 ;;
    --config) CONFIG="$2"; shift 2 ;;
    --wait) WAIT="$2"; shift 2 ;;
    --bag) BAG="$2"; shift 2 ;;
    --launch) LAUNCH="$2"; shift 2 ;;
    -h|--help) sed -n 2,15p "$0"; exit 0 ;;
    *) echo "screenshot_rviz: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[ -f "$CONFIG" ] || { echo "screenshot_rviz: no config '$CONFIG'" >&2; exit 1; }
# rviz silently falls back to its defaults for a malformed file: check the structure first.
python3 - "$CONFIG" <<'EOF' || { echo "screenshot_rviz: FAILED: $CONFIG is no valid rviz config" >&2; exit 1; }
import sys, yaml
try:
    cfg = yaml.safe_load(open(sys.argv[1]))
    vm = cfg["Visualization Manager"]
    displays = vm["Displays"]
    assert isinstance(displays, list) and displays, "no displays"
    assert all("Class" in d and "Name" in d for d in displays), "a display without Class/Name"
    print(f"screenshot_rviz: {len(displays)} displays, fixed frame {vm['Global Options']['Fixed Frame']}")
except Exception as e:
    sys.exit(f"{sys.argv[1]}: {type(e).__name__}: {e}")
EOF

WORK=$(mktemp -d /tmp/screenshot_rviz.XXXXXX)
PIDS=()
cleanup() {
  for ((i = ${#PIDS[@]} - 1; i >= 0; i--)); do
    kill -- "-${PIDS[i]}" 2>/dev/null || kill "${PIDS[i]}" 2>/dev/null
  done
  sleep 1
  for pid in "${PIDS[@]}"; do kill -9 -- "-$pid" 2>/dev/null; done
  [ -n "${OGS_KEEP_WORK:-}" ] && echo "screenshot_rviz: logs kept in $WORK" >&2 || rm -rf "$WORK"
}
trap cleanup EXIT
fail() {
  echo "screenshot_rviz: FAILED: $*" >&2
  [ -f "$WORK/rviz.log" ] && { echo "--- rviz log (last 30 lines)" >&2; tail -n 30 "$WORK/rviz.log" >&2; }
  [ -f "$WORK/launch.log" ] && { echo "--- roslaunch log (last 30 lines)" >&2; tail -n 30 "$WORK/launch.log" >&2; }
  exit 1
}
start() {  # start <log> <command...>: own process group, so cleanup stops its children too
  local log=$1
  shift
  setsid "$@" >"$log" 2>&1 &
  PIDS+=($!)
  disown $!  # no "Killed" job reports at cleanup
}

# A private master on a free port (never 11311).
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
[ "$PORT" != 11311 ] || PORT=$((PORT + 1))
export ROS_MASTER_URI="http://127.0.0.1:$PORT" ROS_HOSTNAME=127.0.0.1 ROS_LOG_DIR="$WORK/ros_log"
start "$WORK/roscore.log" roscore -p "$PORT"
for _ in $(seq 60); do rostopic list >/dev/null 2>&1 && break; sleep 0.5; done
rostopic list >/dev/null 2>&1 || fail "roscore on port $PORT did not come up ($(tail -n 3 "$WORK/roscore.log"))"

# Xvfb on a display it picks itself (-displayfd), frame buffer mapped to an XWD file.
mkdir -p "$WORK/fb" "$(dirname "$OUT")"
start "$WORK/xvfb.log" Xvfb -displayfd 3 -screen 0 1400x900x24 -fbdir "$WORK/fb" -nolisten tcp 3>"$WORK/display"
for _ in $(seq 50); do [ -s "$WORK/display" ] && break; sleep 0.2; done
[ -s "$WORK/display" ] || fail "Xvfb did not start ($(cat "$WORK/xvfb.log"))"
export DISPLAY=":$(head -n1 "$WORK/display")"

if [ -n "$LAUNCH" ]; then
  # shellcheck disable=SC2086
  start "$WORK/launch.log" roslaunch $LAUNCH
fi
if [ -n "$BAG" ]; then
  rosparam set use_sim_time true
  start "$WORK/play.log" rosbag play --clock "$BAG"
fi

LIBGL_ALWAYS_SOFTWARE=1 start "$WORK/rviz.log" rviz -d "$CONFIG"
RVIZ_PID=${PIDS[-1]}
sleep "$WAIT"
kill -0 "$RVIZ_PID" 2>/dev/null || fail "rviz exited while loading $CONFIG"
[ -n "$LAUNCH" ] && cp "$WORK/launch.log" "${OUT%.png}.launch.log"
# rviz reports an unreadable config, an unknown display class or a bad topic type in its log.
if grep -E -i "failed to load|could not be loaded|PluginlibFactory|yaml.*error|error.*yaml|\[ *ERROR\]" "$WORK/rviz.log" >"$WORK/errors"; then
  fail "rviz reported errors for $CONFIG: $(head -n 5 "$WORK/errors")"
fi

python3 - "$WORK/fb/Xvfb_screen0" "$OUT" <<'EOF' || fail "cannot convert the Xvfb frame buffer to PNG"
# XWD (X Window Dump, as Xvfb -fbdir writes it) -> PNG; fails on a blank (single-colour) screen.
import struct, sys
import numpy as np
from PIL import Image
data = open(sys.argv[1], "rb").read()
h = struct.unpack(">25I", data[:100])
header_size, fmt, depth, width, height = h[0], h[2], h[3], h[4], h[5]
bits_per_pixel, bytes_per_line, ncolors = h[11], h[12], h[19]
byte_order = h[7]
if fmt != 2 or bits_per_pixel != 32:
    sys.exit(f"unexpected XWD format {fmt}, {bits_per_pixel} bits per pixel")
start = header_size + 12 * ncolors
rows = np.frombuffer(data, np.uint8, bytes_per_line * height, start).reshape(height, bytes_per_line)
px = rows[:, : width * 4].reshape(height, width, 4)
rgb = px[:, :, [2, 1, 0]] if byte_order == 0 else px[:, :, [1, 2, 3]]  # LSBFirst: B G R x
if len(np.unique(rgb.reshape(-1, 3), axis=0)) < 8:
    sys.exit("the screen is blank: rviz drew nothing")
Image.fromarray(np.ascontiguousarray(rgb)).save(sys.argv[2])
print(f"screenshot_rviz: wrote {sys.argv[2]} ({width}x{height})")
EOF
echo "screenshot_rviz: rviz loaded $CONFIG without errors (display $DISPLAY, master port $PORT)"

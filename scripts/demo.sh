#!/usr/bin/env bash
# The main command (doc/demo.md): install and build, simulate a drive (the procedural city, or a
# real OSM extract with --osm), convert it with kitti2bag, run the ROS system on it (private
# roscore, roslaunch sim.launch, rosbag play --clock, rosservice call save_map) with the perturbed
# OSM prior, run odometry + loops alone on the same data, evaluate both against the ground truth
# and print the table and where the map, the buildings and the plots are.
#
#   scripts/demo.sh [--osm FILE] [--length M] [--out DIR] [--rate R] [--rviz]
#                   [--osm-source file|overpass] [--baseline offline|ros] [--offline]
#                   [--sim-args "OPTIONS"] [--sim-dir DIR] [--skip-build] [--frontend]
#   --osm FILE     OSM extract to drive through (e.g. ../shared/data/osm/2011_09_26_drive_0005_sync.osm);
#                  default: the simulator's procedural city
#   --length M     route length [m] (default: the simulator's 1500)
#   --out DIR      output folder (default build_ws/demo; replaced on each run)
#   --rate R       rosbag play rate (default 0.5: the front-end needs ~70 ms per scan per core,
#                  and scans that arrive faster than it runs are dropped)
#   --rviz         start rviz (needs a display); default headless
#   --osm-source   file (default): osm_buffer reads prior.osm; overpass: prior.osm is served by
#                  scripts/overpass_test_server.py on a free port and osm_buffer queries it
#   --baseline     offline (default): odometry + loops with offline_slam --no-osm (fast);
#                  ros: a second ROS run with use_osm:=false
#   --offline      no ROS master at all: offline_slam for both runs (the bag is not written)
#   --sim-args S   simulate_urban sensor options (default "--motion-distortion
#                  --kitti-calibration-error --rtk": a real sensor's skew and calibration, without
#                  which the simulated odometry hardly drifts, and an exact (RTK) GNSS/INS as in
#                  KITTI, which doc/demo.md's numbers assume; "" = the perfect LiDAR with
#                  consumer-grade GNSS/INS errors), e.g. "--seed 2"
#   --sim-dir DIR  use this earlier simulate_urban output instead of simulating again
#                  (e.g. DIR/sim of an earlier run copied elsewhere; --osm/--length are then ignored)
#   --skip-build   do not run scripts/setup.sh (the workspace is built already)
#   --frontend     only the LiDAR front-end on the real scans of ../shared/data
# Every process this script starts is stopped by its id when it ends (also on Ctrl-C or an error);
# ROS_MASTER_URI is set only inside it. Logs of every step: DIR/logs/.
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH  # pyenv's python3 breaks catkin and the ROS tools
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
WS="${OGS_BUILD_WS:-$ROOT/build_ws}"
DATA="${OGS_SHARED_DATA_DIR:-$ROOT/../shared/data}"
OSM=""
LENGTH=""
OUT="$WS/demo"
RATE=0.5
RVIZ=false
OSM_SOURCE=file
BASELINE=offline
OFFLINE=0
BUILD=1
FRONTEND=0
SIM_DIR=""
SIM_ARGS="--motion-distortion --kitti-calibration-error --rtk"
usage() {
  sed -n 8,28p "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
}
while [ $# -gt 0 ]; do
  case "$1" in
    --osm) OSM="$2"; shift 2 ;;
    --length) LENGTH="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    --rate) RATE="$2"; shift 2 ;;
    --rviz) RVIZ=true; shift ;;
    --osm-source) OSM_SOURCE="$2"; shift 2 ;;
    --baseline) BASELINE="$2"; shift 2 ;;
    --offline) OFFLINE=1; shift ;;
    --sim-dir) SIM_DIR="$2"; shift 2 ;;
    --sim-args) SIM_ARGS="$2"; shift 2 ;;
    --skip-build) BUILD=0; shift ;;
    --frontend) FRONTEND=1; shift ;;
    -h | --help) usage ;;
    *) echo "[demo] unknown argument '$1'" >&2; usage ;;
  esac
done
die() {
  echo "[demo] ERROR: $*" >&2
  exit 1
}
case "$OSM_SOURCE" in file | overpass) ;; *) die "--osm-source takes file or overpass" ;; esac
case "$BASELINE" in offline | ros) ;; *) die "--baseline takes offline or ros" ;; esac
[[ "$RATE" =~ ^[0-9]*\.?[0-9]+$ ]] || die "--rate takes a positive number, not '$RATE'"
[ -z "$LENGTH" ] || [[ "$LENGTH" =~ ^[0-9]+$ ]] || die "--length takes metres, not '$LENGTH'"
if [ -n "$OSM" ]; then
  [ -f "$OSM" ] || die "--osm: no file '$OSM'"
  OSM="$(cd "$(dirname "$OSM")" && pwd)/$(basename "$OSM")"
fi
OUT="$(realpath -m "$OUT")"
if [ -n "$SIM_DIR" ]; then
  [ -f "$SIM_DIR/prior.osm" ] || die "--sim-dir: $SIM_DIR has no prior.osm (not a simulate_urban output)"
  SIM_DIR="$(realpath "$SIM_DIR")"
  case "$SIM_DIR/" in "$OUT"/*) die "--sim-dir must not be inside --out (which is replaced)" ;; esac
fi
if [ "$RVIZ" = true ] && [ -z "${DISPLAY:-}" ]; then
  die "--rviz needs a display (DISPLAY is unset); scripts/screenshot_rviz.sh renders rviz headless"
fi

# --- processes, steps, timings -------------------------------------------------------------------
PIDS=()   # process groups started here (setsid), stopped in reverse order on exit
NAMES=()
STEP_NAMES=()
STEP_SECONDS=()
cleanup() {
  local i pid
  for ((i = ${#PIDS[@]} - 1; i >= 0; i--)); do
    pid=${PIDS[i]}
    kill -0 "$pid" 2>/dev/null || continue
    kill -INT -- "-$pid" 2>/dev/null  # roslaunch and roscore shut their children down on SIGINT
    for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
    if kill -0 "$pid" 2>/dev/null; then
      echo "[demo] ${NAMES[i]} (pid $pid) ignored SIGINT; terminating it" >&2
      kill -TERM -- "-$pid" 2>/dev/null
      sleep 2
      kill -KILL -- "-$pid" 2>/dev/null
    fi
  done
  PIDS=()
  NAMES=()
}
trap cleanup EXIT
trap 'echo "[demo] interrupted" >&2; exit 130' INT TERM
start_bg() {  # start_bg NAME LOG COMMAND...: in its own process group, so cleanup stops its children
  local name=$1 log=$2
  shift 2
  # Background jobs of a script start with SIGINT ignored; roslaunch needs it to shut down cleanly.
  (
    trap - INT QUIT
    exec setsid "$@"
  ) >"$log" 2>&1 &
  PIDS+=($!)
  NAMES+=("$name")
  disown $!  # no "Terminated" job reports at cleanup
}
stop_bg() {  # stop_bg PID: stop one background process group now (SIGINT, then harder)
  local pid=$1 i
  kill -INT -- "-$pid" 2>/dev/null
  for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
  kill -0 "$pid" 2>/dev/null && { kill -TERM -- "-$pid" 2>/dev/null; sleep 2; kill -KILL -- "-$pid" 2>/dev/null; }
  for i in "${!PIDS[@]}"; do [ "${PIDS[i]}" = "$pid" ] && unset 'PIDS[i]' 'NAMES[i]'; done
  PIDS=("${PIDS[@]}")
  NAMES=("${NAMES[@]}")
}
now() { echo "$EPOCHREALTIME"; }
record_step() {  # record_step NAME START
  STEP_NAMES+=("$1")
  STEP_SECONDS+=("$(awk -v a="$2" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }')")
}
fail_step() {  # fail_step STEP LOG MESSAGE
  echo "[demo] FAILED at step '$1': $3" >&2
  if [ -n "$2" ] && [ -f "$2" ]; then
    echo "[demo] last lines of $2:" >&2
    tail -n 25 "$2" | tr '\r' '\n' | tail -n 25 >&2
  fi
  exit 1
}
run_step() {  # run_step NAME LOG COMMAND...: timed, output to LOG, clear failure message
  local name=$1 log=$2 t0
  shift 2
  t0=$(now)
  "$@" >"$log" 2>&1
  local status=$?
  [ "$status" = 0 ] || fail_step "$name" "$log" "$(basename "$1") exited with status $status"
  record_step "$name" "$t0"
}

# The output folder is replaced: only one this script made (marker file), or a new/empty one.
LOGS=""
if [ "$FRONTEND" = 0 ]; then
  MARKER=.osm_graph_slam_demo
  if [ -e "$OUT" ]; then
    if [ -f "$OUT/$MARKER" ]; then
      rm -rf "$OUT"
    elif [ -n "$(ls -A "$OUT" 2>/dev/null)" ]; then
      die "--out $OUT exists and was not written by demo.sh; give a new or empty folder"
    fi
  fi
  mkdir -p "$OUT/logs" || die "cannot create $OUT"
  touch "$OUT/$MARKER"
  LOGS="$OUT/logs"
  SIM="$OUT/sim"
fi

# --- 1. install and build -------------------------------------------------------------------------
T0=$(now)
if [ "$BUILD" = 1 ]; then
  SETUP_LOG="${LOGS:-$(mktemp -d)}/setup.log"
  echo "[demo] 1. install + build (scripts/setup.sh; OGS_JOBS=${OGS_JOBS:-$(nproc)}; log: $SETUP_LOG)"
  "$ROOT/scripts/setup.sh" 2>&1 | tee "$SETUP_LOG"
  [ "${PIPESTATUS[0]}" = 0 ] || die "step 'install + build' failed (scripts/setup.sh; log: $SETUP_LOG)"
  record_step "install + build" "$T0"
fi
BIN="$WS/devel/lib/osm_graph_slam"
for tool in simulate_urban kitti2bag offline_slam evaluate_slam; do
  [ -x "$BIN/$tool" ] || die "$BIN/$tool is missing: build first (scripts/setup.sh)"
done

if [ "$FRONTEND" = 1 ]; then
  [ -f "$DATA/patchwork/000000.bin" ] || die "--frontend needs the real scans of $DATA (patchwork/, kitti00/)"
  "$BIN/frontend_demo" --data "$DATA"
  [ -f "$DATA/kitti00/000094.bin" ] && "$BIN/registration_benchmark" --data "$DATA/kitti00" --runs 3
  exit 0
fi

# --- 2. simulate ------------------------------------------------------------------------------------
if [ -n "$SIM_DIR" ]; then
  echo "[demo] 2. using the simulated drive in $SIM_DIR"
  SIM="$SIM_DIR"
else
  echo "[demo] 2. simulate_urban: ${LENGTH:-the default 1500} m through ${OSM:-the procedural city}" \
    "${SIM_ARGS:+($SIM_ARGS) }-> $SIM"
  read -r -a EXTRA_SIM_ARGS <<<"$SIM_ARGS"
  run_step "simulate" "$LOGS/simulate_urban.log" \
    "$BIN/simulate_urban" --out "$SIM" ${LENGTH:+--length "$LENGTH"} ${OSM:+--osm "$OSM"} "${EXTRA_SIM_ARGS[@]}"
  tr '\r' '\n' <"$LOGS/simulate_urban.log" |
    grep -E "^simulate_urban: [0-9]+ buildings|^prior:|^scans_per_s" | sed 's/^/[demo]   /'
fi
DRIVE=$(ls -d "$SIM"/*/*_drive_*_sync 2>/dev/null | head -n 1)
[ -n "$DRIVE" ] || fail_step "simulate" "$LOGS/simulate_urban.log" "no drive folder in $SIM"
PRIOR="$SIM/prior.osm"

# --- 3. kitti2bag -----------------------------------------------------------------------------------
BAG="$OUT/drive.bag"
if [ "$OFFLINE" = 0 ]; then
  echo "[demo] 3. kitti2bag -> $BAG"
  run_step "kitti2bag" "$LOGS/kitti2bag.log" "$BIN/kitti2bag" "$DRIVE" "$BAG"
  tr '\r' '\n' <"$LOGS/kitti2bag.log" | grep "^kitti2bag: wrote" | sed 's/^/[demo]   /'
else
  echo "[demo] 3. (--offline: no bag)"
fi

# --- 4. SLAM with the OSM prior (and the baseline through ROS with --baseline ros) -----------------
ros_start_master() {
  set +u  # the catkin setup reads unset variables
  # shellcheck disable=SC1091
  source "$WS/devel/setup.bash" || die "cannot source $WS/devel/setup.bash"
  set -u
  local port
  port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  [ "$port" != 11311 ] || port=$((port + 1))
  export ROS_MASTER_URI="http://127.0.0.1:$port" ROS_HOSTNAME=127.0.0.1 ROS_LOG_DIR="$LOGS/ros"
  start_bg roscore "$LOGS/roscore.log" roscore -p "$port"
  for _ in $(seq 60); do rosparam list >/dev/null 2>&1 && break; sleep 0.5; done
  rosparam list >/dev/null 2>&1 || fail_step "roscore" "$LOGS/roscore.log" "roscore on port $port did not come up"
  echo "[demo]   private roscore at $ROS_MASTER_URI (logs: $LOGS/ros)"
  if [ "$OSM_SOURCE" = overpass ]; then
    start_bg overpass_test_server "$LOGS/overpass_test_server.log" \
      python3 "$ROOT/scripts/overpass_test_server.py" --osm "$PRIOR" --port 0 --port-file "$LOGS/overpass.port"
    for _ in $(seq 100); do [ -s "$LOGS/overpass.port" ] && break; sleep 0.2; done
    [ -s "$LOGS/overpass.port" ] || fail_step "overpass server" "$LOGS/overpass_test_server.log" "no port"
    OVERPASS_URL="http://127.0.0.1:$(cat "$LOGS/overpass.port")/api/interpreter"
    echo "[demo]   prior.osm served by scripts/overpass_test_server.py at $OVERPASS_URL"
  fi
}

ros_run() {  # ros_run LABEL USE_OSM DEST: roslaunch, rosbag play, wait, save_map, stop the launch
  local label=$1 use_osm=$2 dest=$3 t0 launch_pid play_status monitor_pid
  local tag=${label// /_}
  local launch_log="$LOGS/roslaunch_$tag.log" play_log="$LOGS/rosbag_play_$tag.log"
  local monitor_log="$LOGS/monitor_$tag.log" report="$LOGS/ros_run_$tag.json"
  local ready="$LOGS/.ready_$tag" bag_done="$LOGS/.bag_done_$tag"
  rm -f "$ready" "$bag_done"
  local args=(osm_file:="$PRIOR" rviz:=$RVIZ use_sim_time:=true use_osm:=$use_osm output:=screen)
  [ "$OSM_SOURCE" = overpass ] && args+=(osm_source:=overpass overpass_url:="$OVERPASS_URL")

  t0=$(now)
  echo "[demo]   roslaunch osm_graph_slam sim.launch ${args[*]}"
  start_bg "roslaunch ($label)" "$launch_log" roslaunch --wait osm_graph_slam sim.launch "${args[@]}"
  launch_pid=${PIDS[-1]}
  # The monitor waits for every nodelet, then counts what the pipeline publishes.
  # (own process group, stopped by cleanup on failure; not disowned: waited for below)
  (
    trap - INT QUIT
    exec setsid python3 "$ROOT/scripts/demo_ros.py" monitor "$BAG" --ready-file "$ready" \
      --bag-done-file "$bag_done" --report "$report"
  ) > >(tee "$monitor_log") 2>&1 &
  monitor_pid=$!
  PIDS+=("$monitor_pid")
  NAMES+=("monitor ($label)")
  local error
  while true; do
    # A nodelet that cannot start (unreadable OSM file, bad parameter, crash) says so in the log.
    error=$(grep -a -m 1 -E "\[(ERROR|FATAL)\]|process has died|RLException" "$launch_log" | sed 's/\x1b\[[0-9;]*m//g')
    [ -z "$error" ] || fail_step "roslaunch ($label)" "$launch_log" "$error"
    [ -f "$ready" ] && break
    kill -0 "$launch_pid" 2>/dev/null || fail_step "roslaunch ($label)" "$launch_log" "roslaunch exited"
    kill -0 "$monitor_pid" 2>/dev/null ||
      fail_step "roslaunch ($label)" "$launch_log" "the nodelets did not come up ($(tail -n 1 "$monitor_log"))"
    sleep 0.5
  done
  record_step "roslaunch $label (nodelets up)" "$t0"

  t0=$(now)
  echo "[demo]   rosbag play --clock -r $RATE $(basename "$BAG") (log: $play_log)"
  rosbag play --clock -q -d 1 -r "$RATE" "$BAG" >"$play_log" 2>&1
  play_status=$?
  touch "$bag_done"
  [ "$play_status" = 0 ] || fail_step "rosbag play ($label)" "$play_log" "rosbag play exited with status $play_status"
  record_step "rosbag play $label (rate $RATE)" "$t0"

  t0=$(now)
  echo "[demo]   waiting for the back-end to process the last keyframe"
  wait "$monitor_pid" || fail_step "wait for the back-end ($label)" "$launch_log" \
    "the pipeline did not finish ($(tail -n 1 "$monitor_log"); monitor log $monitor_log)"
  stop_bg "$monitor_pid"  # exited already: only forgets it
  record_step "back-end catches up $label" "$t0"

  t0=$(now)
  local response
  response=$(rosservice call /graph_backend/save_map "{destination: '$dest', resolution: 0.2}" 2>&1)
  echo "$response" >"$LOGS/save_map_$tag.log"
  grep -q "success: True" <<<"$response" ||
    fail_step "rosservice call save_map ($label)" "$LOGS/save_map_$tag.log" "save_map did not succeed"
  echo "[demo]   save_map: $(grep "^message:" <<<"$response" | cut -c10-)"
  record_step "save_map $label" "$t0"
  stop_bg "$launch_pid"
  python3 - "$report" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))
print("[demo]   front-end: %d of %d scans (%d dropped), %d failed matches, %d keyframes, "
      "%d loop closures" % (r["scans_processed"], r["scans_in_bag"], r["scans_dropped"],
                            r["failed_matches"], r["keyframes"], r["loop_closures"]))
if r["scans_dropped"] > 0:
    print("[demo]   WARNING: %d scans arrived while the front-end was busy and were dropped; "
          "a lower --rate avoids that" % r["scans_dropped"])
EOF
}

EVAL_GT=""
if [ "$OFFLINE" = 0 ]; then
  echo "[demo] 4. ROS: roscore, roslaunch sim.launch, rosbag play, save_map (OSM from $OSM_SOURCE)"
  run_step "ground truth from the bag" "$LOGS/ground_truth.log" \
    python3 "$ROOT/scripts/demo_ros.py" ground-truth "$BAG" "$OUT/ground_truth_tum.txt"
  EVAL_GT="$OUT/ground_truth_tum.txt"
  ros_start_master
  ros_run "with OSM" true "$OUT/slam_osm"
else
  echo "[demo] 4. offline_slam with the perturbed OSM prior ($PRIOR), no ROS master"
  run_step "offline_slam with OSM" "$LOGS/offline_slam_osm.log" \
    "$BIN/offline_slam" --kitti-raw "$DRIVE" --config "$ROOT/config/sim.yaml" --osm "$PRIOR" --output "$OUT/slam_osm"
  grep "scans/s" "$LOGS/offline_slam_osm.log" | tr '\r' '\n' | grep "scans/s" | tail -n 1 | sed 's/^/[demo]   /'
  # The truth of every scan read (not only of the keyframes): coverage sees a lost track.
  EVAL_GT="$OUT/slam_osm/ground_truth_scans_tum.txt"
fi

# --- 5. the baseline: odometry + loops, no OSM ------------------------------------------------------
if [ "$OFFLINE" = 0 ] && [ "$BASELINE" = ros ]; then
  echo "[demo] 5. baseline (odometry + loops, no OSM) through ROS: sim.launch use_osm:=false"
  ros_run "without OSM" false "$OUT/slam_no_osm"
else
  echo "[demo] 5. baseline (odometry + loops, no OSM): offline_slam --no-osm on the same drive" \
    "(the same core pipeline without a ROS master; fast)"
  run_step "offline_slam without OSM (baseline)" "$LOGS/offline_slam_no_osm.log" \
    "$BIN/offline_slam" --kitti-raw "$DRIVE" --config "$ROOT/config/sim.yaml" --no-osm --output "$OUT/slam_no_osm"
  tr '\r' '\n' <"$LOGS/offline_slam_no_osm.log" | grep "scans/s" | tail -n 1 | sed 's/^/[demo]   /'
fi
cleanup  # roscore and the Overpass test server are no longer needed

# --- 6. evaluate -------------------------------------------------------------------------------------
echo "[demo] 6. evaluate_slam + scripts/plot_evaluation.py"
# The SLAM map frame is ENU at the first GPS fix (the first OXTS record); the buildings are
# projected into that frame too so that the plots overlay them on the trajectories.
ORIGIN=$(awk 'NR == 1 { printf "%.9f,%.9f", $1, $2 }' "$DRIVE/oxts/data/0000000000.txt" 2>/dev/null)
[ -n "$ORIGIN" ] || die "step 'evaluate': no first OXTS record in $DRIVE/oxts/data"
EVAL_ARGS=(--estimate "$OUT/slam_osm/trajectory_tum.txt" --ground-truth "$EVAL_GT" --origin "$ORIGIN"
  --baseline "$OUT/slam_no_osm/trajectory_tum.txt" --baseline-label odom+loops
  --buildings-true "$SIM/buildings_true.geojson" --buildings-prior "$PRIOR"
  --buildings-corrected "$OUT/slam_osm/buildings_corrected.geojson")
# offline_slam's run report (tracking counters, the span of the scans read) and accepted loops.
[ -f "$OUT/slam_osm/timing.json" ] && EVAL_ARGS+=(--run-report "$OUT/slam_osm/timing.json")
[ -f "$OUT/slam_osm/loops.txt" ] && EVAL_ARGS+=(--loops "$OUT/slam_osm/loops.txt")
T0=$(now)
"$BIN/evaluate_slam" "${EVAL_ARGS[@]}" --plot-dir "$OUT/plots" >"$OUT/evaluation.txt" 2>"$LOGS/evaluate_slam.log" ||
  fail_step "evaluate" "$LOGS/evaluate_slam.log" "evaluate_slam failed"
"$BIN/evaluate_slam" "${EVAL_ARGS[@]}" --json >"$OUT/evaluation.json" 2>>"$LOGS/evaluate_slam.log" ||
  fail_step "evaluate" "$LOGS/evaluate_slam.log" "evaluate_slam --json failed"
record_step "evaluate + plots" "$T0"

{
  echo "step,wall_s"
  for i in "${!STEP_NAMES[@]}"; do echo "${STEP_NAMES[i]},${STEP_SECONDS[i]}"; done
} >"$OUT/step_times.csv"
RUN="ROS (sim.launch, rosbag play --clock -r $RATE, save_map)"
[ "$OFFLINE" = 1 ] && RUN="offline_slam (no ROS master)"
BASE="offline_slam --no-osm"
[ "$OFFLINE" = 0 ] && [ "$BASELINE" = ros ] && BASE="ROS, sim.launch use_osm:=false"
echo
echo "[demo] SLAM with the OSM prior: $RUN; odom+loops baseline: $BASE"
cat "$OUT/evaluation.txt"
echo
echo "[demo] wall time per step:"
for i in "${!STEP_NAMES[@]}"; do printf "[demo]   %-42s %8.1f s\n" "${STEP_NAMES[i]}" "${STEP_SECONDS[i]}"; done
cat <<MSG

[demo] outputs in $OUT:
  map (point cloud)       slam_osm/map.pcd
  corrected buildings     slam_osm/buildings_corrected.geojson, slam_osm/buildings_corrected.osm
  trajectory, graph       slam_osm/trajectory_{kitti,tum}.txt, slam_osm/graph.g2o
  baseline (no OSM)       slam_no_osm/
  evaluation              evaluation.txt, evaluation.json
  plots                   $(cd "$OUT" && ls plots/*.png 2>/dev/null | tr '\n' ' ')
  simulated drive         ${SIM#"$OUT"/}/ (KITTI raw layout, buildings_true.geojson, prior.osm)$([ "$OFFLINE" = 0 ] && echo "; drive.bag")
  ground truth            ${EVAL_GT#"$OUT"/}
  logs, step times        logs/, step_times.csv
MSG

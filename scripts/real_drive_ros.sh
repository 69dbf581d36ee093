#!/usr/bin/env bash
# The real KITTI drive 2011_09_26_drive_0005 (154 HDL-64E scans, one georeference) through ROS,
# as a user runs it: kitti2bag --scans -> bag; a private roscore; roslaunch osm_graph_slam
# kitti.launch with the OSM extract (osm_source:=file) and without (use_osm:=false); rosbag play
# --clock; rosservice call /graph_backend/save_map (and dump_graph for evaluate_map). Then the
# same scans through offline_slam --scans, and the numbers: scans in the bag vs processed
# (scan_matching_status), keyframes made vs in the saved trajectory, dropped scans, ROS vs
# offline trajectory difference, wall agreement (evaluate_map) and times. doc/real_data.md.
#
#   scripts/real_drive_ros.sh [--out DIR] [--scans DIR] [--rate R] [--runs "osm no_osm"]
#                             [--no-offline] [--no-evaluate]
#   --out DIR    everything goes here (default build_ws/real_drive_ros; replaced)
#   --scans DIR  the unpacked scans (default /tmp/kitti0005/velodyne; unpacked from
#                ../shared/data/kitti_raw_0005/velodyne.tar.xz when missing, never into the repo)
#   --rate R     rosbag play rate (default 1: real time)
#   --runs LIST  which ROS runs: osm (with the OSM extract) and/or no_osm (default both)
#
# Only the processes started here are stopped (their process groups, by id); the master runs on
# a free port (never 11311). Source nothing first: the script sources build_ws/devel/setup.bash.
export PATH=/usr/bin:/bin:$PATH  # pyenv's python3 breaks the ROS tools
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
WS="$ROOT/build_ws"
BIN="$WS/devel/lib/osm_graph_slam"
DATA="$(realpath -m "$ROOT/../shared/data")"
OUT="$WS/real_drive_ros"
SCANS=/tmp/kitti0005/velodyne
RATE=1
RUNS="osm no_osm"
OFFLINE=true
EVALUATE=true
while (($#)); do
  case "$1" in
    --out) OUT="$2"; shift 2 ;;
    --scans) SCANS="$2"; shift 2 ;;
    --rate) RATE="$2"; shift 2 ;;
    --runs) RUNS="$2"; shift 2 ;;
    --no-offline) OFFLINE=false; shift ;;
    --no-evaluate) EVALUATE=false; shift ;;
    -h|--help) sed -n 2,20p "$0"; exit 0 ;;
    *) echo "real_drive_ros: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
die() { echo "real_drive_ros: $*" >&2; exit 1; }
OXTS="$DATA/kitti_raw_0005/oxts_frame0.txt"
CALIB="$DATA/kitti_raw_0005/calib_2011_09_26.txt"
OSM="$DATA/osm/2011_09_26_drive_0005_sync.osm"
for f in "$OXTS" "$CALIB" "$OSM"; do [ -f "$f" ] || die "missing $f (the real data lives in ../shared/data)"; done
for t in kitti2bag offline_slam evaluate_map; do
  [ -x "$BIN/$t" ] || die "$BIN/$t is not built (/tmp/ogs_make.sh $t, or scripts/setup.sh)"
done
OUT="$(realpath -m "$OUT")"
case "$OUT/" in "$ROOT"/build_ws/*|/tmp/*) ;; *) die "--out must be under build_ws/ or /tmp (it is replaced)";; esac
rm -rf "$OUT"
mkdir -p "$OUT/logs"
LOGS="$OUT/logs"

if [ ! -f "$SCANS/0000000000.bin" ]; then
  echo "[real] unpacking $DATA/kitti_raw_0005/velodyne.tar.xz into $(dirname "$SCANS")"
  mkdir -p "$(dirname "$SCANS")"
  tar xJf "$DATA/kitti_raw_0005/velodyne.tar.xz" -C "$(dirname "$SCANS")" || die "cannot unpack the scans"
fi
SCANS="$(realpath "$SCANS")"

# --- processes: own process groups, stopped in reverse order ---------------------------------------
PIDS=()
cleanup() {
  local i pid
  for ((i = ${#PIDS[@]} - 1; i >= 0; i--)); do
    pid=${PIDS[i]}
    kill -0 "$pid" 2>/dev/null || continue
    kill -INT -- "-$pid" 2>/dev/null  # roslaunch and roscore shut their children down on SIGINT
    for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
    kill -0 "$pid" 2>/dev/null && { kill -TERM -- "-$pid" 2>/dev/null; sleep 2; kill -KILL -- "-$pid" 2>/dev/null; }
  done
  PIDS=()
}
trap cleanup EXIT
trap 'echo "[real] interrupted" >&2; exit 130' INT TERM
start_bg() {  # start_bg LOG COMMAND...: in its own process group
  local log=$1
  shift
  (
    trap - INT QUIT  # background jobs start with SIGINT ignored; roslaunch needs it
    exec setsid "$@"
  ) >"$log" 2>&1 &
  PIDS+=($!)
  disown $!
}
stop_bg() {  # stop_bg PID
  local pid=$1 i
  kill -INT -- "-$pid" 2>/dev/null
  for _ in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
  kill -0 "$pid" 2>/dev/null && { kill -TERM -- "-$pid" 2>/dev/null; sleep 2; kill -KILL -- "-$pid" 2>/dev/null; }
  for i in "${!PIDS[@]}"; do [ "${PIDS[i]}" = "$pid" ] && unset 'PIDS[i]'; done
  PIDS=("${PIDS[@]}")
}
now() { date +%s.%N; }
since() { python3 -c "import sys; print('%.1f' % (float(sys.argv[2]) - float(sys.argv[1])))" "$1" "$(now)"; }

# --- 1. the bag ----------------------------------------------------------------------------------------
BAG="$OUT/kitti_0005_scans.bag"
t0=$(now)
"$BIN/kitti2bag" --scans "$SCANS" --origin-oxts "$OXTS" --calib "$CALIB" "$BAG" 2>"$LOGS/kitti2bag.log" ||
  { cat "$LOGS/kitti2bag.log" >&2; die "kitti2bag failed"; }
T_KITTI2BAG=$(since "$t0")
KITTI2BAG_LINE=$(grep "kitti2bag: wrote" "$LOGS/kitti2bag.log")
ROS_START=$(sed -n 's/.*first stamp \([0-9.]*\).*/\1/p' <<<"$KITTI2BAG_LINE")
echo "[real] 1. ${KITTI2BAG_LINE#kitti2bag: } (${T_KITTI2BAG} s)"

# --- 2. ROS --------------------------------------------------------------------------------------------
set +u
# shellcheck disable=SC1091
source "$WS/devel/setup.bash" || die "cannot source $WS/devel/setup.bash"
set -u
PORT=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
[ "$PORT" != 11311 ] || PORT=$((PORT + 1))
export ROS_MASTER_URI="http://127.0.0.1:$PORT" ROS_HOSTNAME=127.0.0.1 ROS_LOG_DIR="$LOGS/ros"
start_bg "$LOGS/roscore.log" roscore -p "$PORT"
for _ in $(seq 60); do rosparam list >/dev/null 2>&1 && break; sleep 0.5; done
rosparam list >/dev/null 2>&1 || die "roscore on port $PORT did not come up ($(tail -n 3 "$LOGS/roscore.log"))"
echo "[real] 2. private roscore at $ROS_MASTER_URI"

ros_run() {  # ros_run TAG USE_OSM
  local tag=$1 use_osm=$2 t0 launch_pid monitor_pid error response
  local dest="$OUT/ros_$tag" launch_log="$LOGS/roslaunch_$tag.log" report="$LOGS/ros_$tag.json"
  local ready="$LOGS/.ready_$tag" bag_done="$LOGS/.bag_done_$tag"
  # osm_buffer sets the map origin from gps/fix in both runs; the file source keeps the baseline
  # off the network (with use_osm:=false the back-end ignores the buildings).
  local args=(osm_source:=file osm_file:="$OSM" use_osm:="$use_osm" use_sim_time:=true output:=screen)
  echo "[real]   $tag: roslaunch osm_graph_slam kitti.launch ${args[*]}"
  t0=$(now)
  start_bg "$launch_log" roslaunch --wait osm_graph_slam kitti.launch "${args[@]}"
  launch_pid=${PIDS[-1]}
  (
    trap - INT QUIT
    exec setsid python3 "$ROOT/scripts/demo_ros.py" monitor "$BAG" --ready-file "$ready" \
      --bag-done-file "$bag_done" --report "$report" --print-period 10 --timeout 120
  ) >"$LOGS/monitor_$tag.log" 2>&1 &
  monitor_pid=$!
  PIDS+=("$monitor_pid")
  while true; do
    error=$(grep -a -m 1 -E "\[(ERROR|FATAL)\]|process has died|RLException" "$launch_log" | sed 's/\x1b\[[0-9;]*m//g')
    [ -z "$error" ] || die "roslaunch ($tag): $error (log $launch_log)"
    [ -f "$ready" ] && break
    kill -0 "$launch_pid" 2>/dev/null || die "roslaunch ($tag) exited (log $launch_log)"
    kill -0 "$monitor_pid" 2>/dev/null || die "the nodelets did not come up ($(tail -n 1 "$LOGS/monitor_$tag.log"))"
    sleep 0.5
  done
  local t_up t_play t_catch
  t_up=$(since "$t0")
  t0=$(now)
  # --wait-for-subscribers: the first scan (the georeferenced one) is not played before the
  # nodelets' subscriptions are connected (on a loaded machine that took more than -d 1).
  rosbag play --clock -q -d 1 --wait-for-subscribers -r "$RATE" "$BAG" >"$LOGS/rosbag_play_$tag.log" 2>&1 ||
    die "rosbag play ($tag) failed (log $LOGS/rosbag_play_$tag.log)"
  touch "$bag_done"
  t_play=$(since "$t0")
  t0=$(now)
  wait "$monitor_pid" || die "the pipeline did not finish ($tag): $(tail -n 2 "$LOGS/monitor_$tag.log")"
  stop_bg "$monitor_pid"
  t_catch=$(since "$t0")
  response=$(rosservice call /graph_backend/save_map "{destination: '$dest', resolution: 0.2}" 2>&1)
  echo "$response" >"$LOGS/save_map_$tag.log"
  grep -q "success: True" <<<"$response" || die "save_map ($tag) failed: $response"
  response=$(rosservice call /graph_backend/dump_graph "{destination: '$dest/dump'}" 2>&1)
  echo "$response" >"$LOGS/dump_graph_$tag.log"
  grep -q "success: True" <<<"$response" || die "dump_graph ($tag) failed: $response"
  stop_bg "$launch_pid"
  python3 - "$report" "$t_up" "$t_play" "$t_catch" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))
r.update(nodelets_up_s=float(sys.argv[2]), bag_play_s=float(sys.argv[3]),
         catch_up_after_bag_s=float(sys.argv[4]))
json.dump(r, open(sys.argv[1], "w"), indent=1)
EOF
  # What the nodelets said about the single fix / single IMU sample (the input a scan folder gives).
  sed 's/\x1b\[[0-9;]*m//g' "$launch_log" >"$launch_log.txt"
  grep -a -E "ENU origin set|map origin|initial heading" "$launch_log.txt" | sed 's/^/[real]     /'
  echo "[real]     $(grep -a -c "\[ WARN\]" "$launch_log.txt") warnings in the launch log; front-end:" \
    "$(python3 -c "import json,sys; r=json.load(open(sys.argv[1])); print('%d/%d scans, %d keyframes' % (r['scans_processed'], r['scans_in_bag'], r['keyframes']))" "$report")"
}

for run in $RUNS; do
  case "$run" in
    osm) ros_run osm true ;;
    no_osm) ros_run no_osm false ;;
    *) die "--runs: unknown run '$run' (osm, no_osm)" ;;
  esac
done
cleanup  # the master is no longer needed

# --- 3. offline_slam on the same scans ------------------------------------------------------------------
if [ "$OFFLINE" = true ]; then
  for run in $RUNS; do
    echo "[real] 3. offline_slam --scans ($run)"
    flag=(--osm "$OSM")
    [ "$run" = no_osm ] && flag=(--no-osm)
    t0=$(now)
    "$BIN/offline_slam" --scans "$SCANS" --origin-oxts "$OXTS" --calib "$CALIB" "${flag[@]}" \
      --output "$OUT/offline_$run" --dump "$OUT/offline_$run/dump" --json \
      >"$OUT/offline_$run.json" 2>"$LOGS/offline_$run.log" ||
      { tail -n 5 "$LOGS/offline_$run.log" >&2; die "offline_slam ($run) failed"; }
    since "$t0" >"$LOGS/offline_$run.seconds"
  done
fi

# --- 4. evaluate_map on the ROS runs ---------------------------------------------------------------------
if [ "$EVALUATE" = true ] && [[ " $RUNS " == *" osm "* ]]; then
  base=()
  [[ " $RUNS " == *" no_osm "* ]] && base=(--baseline "$OUT/ros_no_osm")
  "$BIN/evaluate_map" --run "$OUT/ros_osm" "${base[@]}" --json >"$OUT/evaluate_map_ros.json" 2>"$LOGS/evaluate_map_ros.log" ||
    echo "[real] evaluate_map (ROS) failed: $(tail -n 2 "$LOGS/evaluate_map_ros.log")" >&2
  if [ "$OFFLINE" = true ]; then
    base=()
    [[ " $RUNS " == *" no_osm "* ]] && base=(--baseline "$OUT/offline_no_osm")
    "$BIN/evaluate_map" --run "$OUT/offline_osm" "${base[@]}" --json >"$OUT/evaluate_map_offline.json" 2>"$LOGS/evaluate_map_offline.log" ||
      echo "[real] evaluate_map (offline) failed: $(tail -n 2 "$LOGS/evaluate_map_offline.log")" >&2
  fi
fi

# --- 5. the numbers ----------------------------------------------------------------------------------------
# Keyframes are matched by scan index: the bag's stamps are ROS_START + i / 10, offline_slam
# --scans stamps scan i at 1.0 + i / 10 (its kFirstStamp).
python3 - "$OUT" "$ROS_START" "$RUNS" "$OFFLINE" "$RATE" <<'EOF'
import json, math, os, sys
out, ros_start, runs = sys.argv[1], float(sys.argv[2]), sys.argv[3].split()
offline, play_rate = sys.argv[4] == "true", sys.argv[5]
RATE, OFFLINE_START = 10.0, 1.0

def tum(path, start):
    poses = {}
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        v = [float(x) for x in line.split()]
        poses[int(round((v[0] - start) * RATE))] = v[1:]
    return poses

def yaw(q):
    x, y, z, w = q
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))

def diff(a, b):
    common = sorted(set(a) & set(b))
    d = [math.dist(a[i][:3], b[i][:3]) for i in common]
    dyaw = [abs(math.degrees(math.remainder(yaw(a[i][3:]) - yaw(b[i][3:]), 2 * math.pi)))
            for i in common]
    return dict(common=len(common), only_first=len(set(a) - set(b)), only_second=len(set(b) - set(a)),
                max_m=max(d) if d else float("nan"), mean_m=sum(d) / len(d) if d else float("nan"),
                max_yaw_deg=max(dyaw) if dyaw else float("nan"))

summary = {}
print("\n== real drive 0005 through ROS (rosbag play -r %s) ==" % play_rate)
print("%-8s %6s %9s %7s %7s %10s %10s %8s %7s %7s" % ("run", "bag", "processed", "dropped", "failed",
      "keyframes", "saved traj", "in path", "play s", "wait s"))
for run in runs:
    r = json.load(open(os.path.join(out, "logs", "ros_%s.json" % run)))
    ros = tum(os.path.join(out, "ros_" + run, "trajectory_tum.txt"), ros_start)
    row = dict(r, saved_keyframes=len(ros))
    print("%-8s %6d %9d %7d %7d %10d %10d %8d %7.1f %7.1f" % (
        run, r["scans_in_bag"], r["scans_processed"], r["scans_dropped"], r["failed_matches"],
        r["keyframes"], len(ros), r["backend_path_keyframes"], r["bag_play_s"],
        r["catch_up_after_bag_s"]))
    if offline:
        off_dir = os.path.join(out, "offline_" + run)
        off = tum(os.path.join(off_dir, "trajectory_tum.txt"), OFFLINE_START)
        t = json.load(open(os.path.join(out, "offline_%s.json" % run)))
        row["offline_keyframes"] = len(off)
        row["offline"] = dict(scans=t["scans"], matched=t["tracking"]["matched"],
                              lost_events=t["tracking"]["lost_events"],
                              building_edges=t["map_priors"]["building_edges"],
                              wall_time_s=t["wall_time_s"], scans_per_second=t["scans_per_second"],
                              run_s=float(open(os.path.join(out, "logs", "offline_%s.seconds" % run)).read()))
        row["ros_vs_offline"] = diff(ros, off)
    summary[run] = row
if offline:
    print("\nROS vs offline_slam --scans (keyframes matched by scan index):")
    for run, row in summary.items():
        d = row["ros_vs_offline"]
        print("  %-7s ROS %d / offline %d keyframes, %d common (%d only ROS, %d only offline): "
              "position max %.3f m, mean %.3f m; yaw max %.3f deg" % (
                  run, row["saved_keyframes"], row["offline_keyframes"], d["common"],
                  d["only_first"], d["only_second"], d["max_m"], d["mean_m"], d["max_yaw_deg"]))
if "osm" in summary and "no_osm" in summary:
    a = tum(os.path.join(out, "ros_osm", "trajectory_tum.txt"), ros_start)
    b = tum(os.path.join(out, "ros_no_osm", "trajectory_tum.txt"), ros_start)
    d = diff(a, b)
    summary["ros_osm_vs_ros_no_osm"] = d
    print("ROS with vs without OSM: %d common keyframes, max %.3f m, mean %.3f m" % (
        d["common"], d["max_m"], d["mean_m"]))
for name in ("ros", "offline"):
    path = os.path.join(out, "evaluate_map_%s.json" % name)
    if not os.path.exists(path) or os.path.getsize(path) == 0:
        continue
    e = json.load(open(path))
    summary["evaluate_map_" + name] = e
    w, b = e.get("walls", {}), e.get("baseline")
    line = "evaluate_map %-7s: %d keyframes" % (name, e["keyframes"])
    if w:
        line += (", walls to outline (median over %d observed buildings): prior %.3f -> corrected "
                 "%.3f m, largest unobserved shift %.2f m" % (
                     w["observed_buildings"], w["prior_median_m"], w["corrected_median_m"],
                     w["max_unobserved_shift_m"]))
    line += ", plane variance %.5f m^2" % e["sharpness"]["mean_plane_variance"]
    if b:
        line += " (%+.1f %% vs without OSM; trajectories %.3f / %.3f m max / mean)" % (
            100 * b["sharpness_change"], b["trajectory_difference_max_m"],
            b["trajectory_difference_mean_m"])
    print(line)
if offline:
    for run, row in summary.items():
        if run in runs:
            o = row["offline"]
            print("offline_slam %-7s: %d/%d scans matched, %d lost, %d building edges, %.1f scans/s "
                  "(%.1f s wall)" % (run, o["matched"], o["scans"], o["lost_events"],
                                     o["building_edges"], o["scans_per_second"], o["wall_time_s"]))
json.dump(summary, open(os.path.join(out, "summary.json"), "w"), indent=1)
print("\nsummary: %s" % os.path.join(out, "summary.json"))
EOF

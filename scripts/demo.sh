#!/usr/bin/env bash
# The main job: install and build, simulate a drive through real OSM geometry (the Karlsruhe
# extract of ../shared/data when present, else the procedural city), run the whole SLAM pipeline
# on it with the perturbed OSM prior and without it (odometry + loops only), evaluate both against
# the ground truth (trajectory and buildings) and write plots.
#   scripts/demo.sh [--length M] [--osm FILE] [--out DIR] [--frontend]
# --frontend runs only the LiDAR front-end on the real KITTI scans (the earlier demo).
# Run through ROS instead: see README.md (launch/sim.launch + rosbag play + save_map).
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
WS="${OGS_BUILD_WS:-$ROOT/build_ws}"
DATA="${OGS_SHARED_DATA_DIR:-$ROOT/../shared/data}"
LENGTH=400
OUT="$WS/demo"
OSM=""
FRONTEND=0
while [ $# -gt 0 ]; do
  case "$1" in
    --length) LENGTH="$2"; shift 2 ;;
    --osm) OSM="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    --frontend) FRONTEND=1; shift ;;
    *) echo "usage: scripts/demo.sh [--length M] [--osm FILE] [--out DIR] [--frontend]" >&2; exit 2 ;;
  esac
done
"$ROOT/scripts/setup.sh"
BIN="$WS/devel/lib/osm_graph_slam"

if [ "$FRONTEND" = 1 ]; then
  if [ ! -f "$DATA/patchwork/000000.bin" ]; then
    echo "[demo] --frontend needs the real scans of ../shared/data (patchwork/, kitti00/)" >&2
    exit 1
  fi
  "$BIN/frontend_demo" --data "$DATA"
  [ -f "$DATA/kitti00/000094.bin" ] && "$BIN/registration_benchmark" --data "$DATA/kitti00" --runs 3
  exit 0
fi

if [ -z "$OSM" ] && [ -f "$DATA/osm/2011_09_26_drive_0005_sync.osm" ]; then
  OSM="$DATA/osm/2011_09_26_drive_0005_sync.osm"
fi
rm -rf "$OUT"
mkdir -p "$OUT"
SIM="$OUT/sim"
echo "[demo] 1/4 simulating a ${LENGTH} m drive through ${OSM:-the procedural city} -> $SIM"
"$BIN/simulate_urban" --out "$SIM" --length "$LENGTH" ${OSM:+--osm "$OSM"} | tail -n 6
DRIVE=$(ls -d "$SIM"/*/*_drive_*_sync | head -n 1)

echo "[demo] 2/4 SLAM with the perturbed OSM prior ($SIM/prior.osm)"
"$BIN/offline_slam" --kitti-raw "$DRIVE" --osm "$SIM/prior.osm" --output "$OUT/slam_osm" 2>/dev/null
echo "[demo] 3/4 SLAM without OSM (odometry + loops)"
"$BIN/offline_slam" --kitti-raw "$DRIVE" --no-osm --output "$OUT/slam_no_osm" 2>/dev/null | tail -n 1

echo "[demo] 4/4 evaluation against the ground truth"
"$BIN/evaluate_slam" --estimate "$OUT/slam_osm/trajectory_tum.txt" \
  --ground-truth "$OUT/slam_osm/ground_truth_tum.txt" \
  --baseline "$OUT/slam_no_osm/trajectory_tum.txt" --baseline-label odom+loops \
  --buildings-true "$SIM/buildings_true.geojson" --buildings-prior "$SIM/prior.osm" \
  --buildings-corrected "$OUT/slam_osm/buildings_corrected.geojson" --max-dt 0.001 \
  --plot-dir "$OUT/plots" 2>/dev/null | tee "$OUT/evaluation.txt"
cat <<MSG

[demo] outputs in $OUT:
  slam_osm/map.pcd, slam_osm/buildings_corrected.{geojson,osm}, slam_osm/trajectory_{kitti,tum}.txt,
  slam_osm/graph.g2o, slam_osm/timing.txt; plots/*.png; evaluation.txt
MSG

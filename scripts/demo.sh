#!/usr/bin/env bash
# The main job. Until the full pipeline lands, it builds the project and runs the LiDAR front-end
# (prefilter + scan-to-keyframe odometry) on the real scans of ../shared/data, then the
# registration benchmark (ours vs PCL GICP/NDT) on the KITTI 00 pair.
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
WS="${OGS_BUILD_WS:-$ROOT/build_ws}"
DATA="${OGS_SHARED_DATA_DIR:-$ROOT/../shared/data}"
"$ROOT/scripts/setup.sh"
BIN="$WS/devel/lib/osm_graph_slam"

if [ ! -f "$DATA/patchwork/000000.bin" ] && [ ! -f "$DATA/kitti00/000094.bin" ]; then
  cat >&2 <<MSG
[demo] the front-end demo needs real LiDAR scans, which are not part of this repository:
[demo]   $DATA/patchwork/000000.bin ... 000005.bin   (six consecutive HDL-64E scans)
[demo]   $DATA/kitti00/000094.bin, 000095.bin, gt_relative_lidar.txt   (KITTI 00)
[demo] Put them there (see ../shared/data/README.md), or set OGS_SHARED_DATA_DIR, or run
[demo]   $BIN/frontend_demo --scans <folder of KITTI .bin scans>
MSG
  exit 1
fi

echo "[demo] LiDAR front-end (prefilter + scan-to-keyframe tracker) on $DATA"
"$BIN/frontend_demo" --data "$DATA"
if [ -f "$DATA/kitti00/000094.bin" ]; then
  echo
  echo "[demo] registration benchmark on KITTI 00 94->95 (ours vs PCL GICP / NDT)"
  "$BIN/registration_benchmark" --data "$DATA/kitti00" --runs 3
fi

#!/usr/bin/env bash
# Installs every Debian package osm_graph_slam needs (idempotent; apt-get only when something is
# missing) and builds the catkin workspace in build_ws/ (the package is linked into build_ws/src).
#   scripts/setup.sh            install + build
#   scripts/setup.sh --no-build install only
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH   # pyenv's python3 breaks catkin
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
WS="${OGS_BUILD_WS:-$ROOT/build_ws}"
JOBS="${OGS_JOBS:-$(nproc)}"

PACKAGES=(
  # toolchain
  cmake g++ make pkg-config clang-format
  # ROS 1 from Debian
  catkin ros-base-dev rosbash python3-rostest python3-roslaunch python3-rosbag
  libnodeletlib-dev libnodeletlib-tools libnodelet-dev pluginlib-dev librosbag-dev
  libtf2-ros-dev libtf2-eigen-dev libtf2-geometry-msgs-dev libtf2-sensor-msgs-dev
  libpcl-ros-dev libpcl-conversions-dev ros-message-generation ros-message-runtime
  ros-std-msgs ros-std-srvs ros-sensor-msgs ros-nav-msgs ros-geometry-msgs
  ros-visualization-msgs ros-tf2-msgs ros-diagnostic-msgs libdiagnostic-msgs-dev rviz
  # algorithms
  libpcl-dev libeigen3-dev libceres-dev libsuitesparse-dev libgeographiclib-dev libopencv-dev
  libosmium2-dev libprotozero-dev libbz2-dev libexpat1-dev zlib1g-dev liblz4-dev
  libcurl4-openssl-dev libnanoflann-dev libtbb-dev nlohmann-json3-dev libyaml-cpp-dev
  # tests, plots, screenshots
  libgtest-dev googletest python3-matplotlib python3-numpy xvfb xauth
  # scripts/fleet_map.py and slam_matrix.py --executor dask (python3-distributed brings
  # psutil, tornado, cloudpickle, msgpack)
  python3-distributed python3-dask
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "[setup] installing ${#missing[@]} missing Debian packages: ${missing[*]}"
  if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
else
  echo "[setup] all ${#PACKAGES[@]} Debian packages present"
fi

[ "${1:-}" = "--no-build" ] && exit 0

# The package in the workspace is a folder of links to the checkout's entries, not one link to
# the checkout: a link to the checkout would contain build_ws itself, and roslaunch/rostest
# (which walk package folders following links) would then recurse forever.
PKG="$WS/src/osm_graph_slam"
mkdir -p "$WS/src"
[ -L "$PKG" ] && rm "$PKG"
mkdir -p "$PKG"
for entry in "$ROOT"/* "$ROOT"/.clang-format; do
  name=$(basename "$entry")
  [ "$entry" = "$WS" ] || [ "$name" = build_ws ] && continue
  ln -sfn "$entry" "$PKG/$name"
done
for link in "$PKG"/* "$PKG"/.[!.]*; do
  [ -L "$link" ] && [ ! -e "$link" ] && rm -f "$link"
done
cd "$WS"
echo "[setup] building catkin workspace $WS (-j$JOBS)"
set +e
# OGS_CMAKE_ARGS: extra CMake arguments (scripts/test.sh --sanitize builds its own workspace so).
# shellcheck disable=SC2086
catkin_make -DCMAKE_BUILD_TYPE=Release -DPYTHON_EXECUTABLE=/usr/bin/python3 ${OGS_CMAKE_ARGS:-} \
  -j"$JOBS" ${OGS_MAKE_TARGETS:-} 2>&1 | tee "$WS/build.log" |
  grep --line-buffered -E '^\[ *[0-9]+%\] Building|error:|Error [0-9]|CMake Error'
status=${PIPESTATUS[0]}
set -e
if [ "$status" -ne 0 ]; then
  echo "[setup] build FAILED (exit $status); full log: $WS/build.log" >&2
  tail -n 40 "$WS/build.log" >&2
  exit 1
fi
echo "[setup] done: tools in $WS/devel/lib/osm_graph_slam/, source $WS/devel/setup.bash"

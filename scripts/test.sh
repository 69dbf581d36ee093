#!/usr/bin/env bash
# Runs setup (install + build), then every gtest and rostest of osm_graph_slam.
# Exits non-zero on any failure; the last line is "N passed, N failed, N skipped".
#   scripts/test.sh              the above (what CI runs)
#   scripts/test.sh --sanitize   builds every gtest with AddressSanitizer + UndefinedBehavior-
#                                Sanitizer in a workspace of its own (build_ws/sanitize) and runs
#                                them; any sanitizer report fails (doc/reliability.md)
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH   # pyenv's python3 breaks catkin
set -o pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ "${1:-}" = "--sanitize" ]; then
  shift
  exec "$ROOT/scripts/test_sanitize.sh" "$@"
fi
WS="${OGS_BUILD_WS:-$ROOT/build_ws}"
JOBS="${OGS_JOBS:-$(nproc)}"

"$ROOT/scripts/setup.sh" || { echo "0 passed, 1 failed"; exit 1; }

# shellcheck disable=SC1091
source "$WS/devel/setup.bash"
# rostests start their own master on a port of their own; never touch a user's roscore.
export ROS_MASTER_URI="http://127.0.0.1:${OGS_TEST_ROS_PORT:-22422}"
export ROS_HOME="$WS/ros_home"
export ROS_LOG_DIR="$WS/ros_home/log"
mkdir -p "$ROS_LOG_DIR"

# A full run leaves 2.2 GB in build_ws (build, simulated drives, bags, maps) and
# writes < 1 GB to /tmp; a full disk otherwise shows up as unrelated write errors in the tests.
free_gb() { df -P -k "$1" 2>/dev/null | awk 'NR == 2 { printf "%.1f", $4 / 1048576 }'; }
for dir in "$WS" "${TMPDIR:-/tmp}"; do
  gb="$(free_gb "$dir")"
  echo "[test] ${gb:-?} GB free on the file system of $dir"
  if [ -n "$gb" ] && awk -v g="$gb" -v need="${OGS_TEST_MIN_FREE_GB:-5}" 'BEGIN { exit !(g < need) }'; then
    echo "[test] WARNING: less than ${OGS_TEST_MIN_FREE_GB:-5} GB free on $dir: the regression tests may fail with write errors"
  fi
done

rm -rf "$WS/build/test_results"
cd "$WS"
echo "[test] building and running tests (-j$JOBS)"
catkin_make -j"$JOBS" run_tests ${OGS_TEST_TARGETS:-} > "$WS/test.log" 2>&1
build_status=$?
# Show each test's outcome lines (gtest and rostest) without the build noise.
grep -E '^\[ *(OK|FAILED|SKIPPED|PASSED|RUN) *\]|^\[ROSTEST\]|^\[Testcase|FAILURE|error:|Error [0-9]' \
  "$WS/test.log" | grep -v '^\[ RUN' || true

# Python tests of the scripts (slam_matrix.py); their JUnit XML joins the others.
echo "[test] python tests (test/scripts)"
/usr/bin/python3 "$ROOT/scripts/run_python_tests.py" "$WS/build/test_results/python/scripts.xml" \
  > "$WS/python_tests.log" 2>&1 || grep -E "^(FAIL|ERROR):" "$WS/python_tests.log"

if grep -q "No space left on device" "$WS/test.log"; then
  echo "[test] the disk ran full during the tests (\"No space left on device\" in build_ws/test.log): free space and run again"
fi
/usr/bin/python3 "$ROOT/scripts/test_summary.py" "$WS/build/test_results" --build-status "$build_status"

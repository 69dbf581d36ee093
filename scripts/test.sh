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

/usr/bin/python3 "$ROOT/scripts/test_summary.py" "$WS/build/test_results" --build-status "$build_status"

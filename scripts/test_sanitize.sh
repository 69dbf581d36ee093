#!/usr/bin/env bash
# scripts/test.sh --sanitize: every gtest of test/unit built with AddressSanitizer (+ LeakSanitizer)
# and UndefinedBehaviorSanitizer in a catkin workspace of its own, then run; a sanitizer report
# fails the test program. The last line is "N passed, N failed, N skipped" as for scripts/test.sh.
#
#   OGS_SANITIZE_WS   workspace (default build_ws/sanitize)
#   OGS_JOBS          parallel compiles (default nproc)
#   OGS_BUILD_LOCK    a lock file taken around each compile step (shared machines), default none
#   OGS_SANITIZE_TESTS  space-separated gtest names (default: all of test/unit)
#   OGS_SANITIZE_ROSTESTS  rostests run with the instrumented nodelets (default
#                       "fault_injection.test slam_pipeline.test"; empty: none)
#   OGS_TEST_ROS_PORT   ROS master port of those rostests (default 22423)
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH   # pyenv's python3 breaks catkin
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
WS="${OGS_SANITIZE_WS:-$ROOT/build_ws/sanitize}"
JOBS="${OGS_JOBS:-$(nproc)}"
START=$(date +%s)
locked() {
  if [ -n "${OGS_BUILD_LOCK:-}" ]; then flock "$OGS_BUILD_LOCK" nice -n 15 "$@"; else "$@"; fi
}

# failure_xml FILE NAME MESSAGE: a JUnit file with one failed case, read by test_summary.py.
failure_xml() {
  python3 - "$@" <<'PY'
import sys
from xml.sax.saxutils import quoteattr
path, name, message = sys.argv[1:4]
open(path, "w").write('<testsuites><testsuite name=%s><testcase classname="sanitize" name=%s>'
    '<failure message=%s/></testcase></testsuite></testsuites>\n' % (quoteattr(name), quoteattr(name), quoteattr(message)))
PY
}

# Packages and the workspace (configured only; the targets are built below).
OGS_BUILD_WS="$WS" OGS_MAKE_TARGETS=cmake_check_build_system \
  OGS_CMAKE_ARGS="-DCMAKE_TOOLCHAIN_FILE=$ROOT/test/sanitize/sanitize.cmake" \
  locked "$ROOT/scripts/setup.sh" || { echo "0 passed, 1 failed"; exit 1; }

if [ -n "${OGS_SANITIZE_TESTS:-}" ]; then
  read -r -a TESTS <<< "$OGS_SANITIZE_TESTS"
else
  TESTS=()
  for f in "$ROOT"/test/unit/*_test.cpp; do TESTS+=("$(basename "$f" .cpp)"); done
fi
read -r -a ROSTESTS <<< "${OGS_SANITIZE_ROSTESTS-fault_injection.test slam_pipeline.test}"
# A rostest needs the nodelet plugins and its test nodes (type="..._node" in the .test file).
ROSTEST_TARGETS=()
for r in "${ROSTESTS[@]}"; do
  ROSTEST_TARGETS+=(osm_graph_slam_nodelets)
  for node in $(grep -o 'type="[a-z_]*_node"' "$ROOT/test/rostest/$r" | cut -d'"' -f2); do
    ROSTEST_TARGETS+=("$node")
  done
done

echo "[sanitize] building ${#TESTS[@]} gtests with ASan + UBSan in $WS (-j$JOBS)"
build_status=0
: > "$WS/sanitize_build.log"
# The libraries first, then the tools gtests run (real_drive_test: offline_slam and
# evaluate_map, instrumented too), then each test on its own so that a lock is never held long.
for target in osm_graph_slam_core osm_graph_slam_ros offline_slam evaluate_map "${TESTS[@]}" \
  $(printf '%s\n' "${ROSTEST_TARGETS[@]}" | sort -u); do
  if ! locked make -C "$WS/build" -j"$JOBS" "$target" >> "$WS/sanitize_build.log" 2>&1; then
    echo "[sanitize] build of $target FAILED (log $WS/sanitize_build.log)"
    grep -E "error:|Error [0-9]" "$WS/sanitize_build.log" | tail -10
    build_status=1
  fi
done
BUILT=$(date +%s)
echo "[sanitize] build took $((BUILT - START)) s"

RESULTS="$WS/test_results"
LOGS="$WS/test_logs"
rm -rf "$RESULTS" "$LOGS"
mkdir -p "$RESULTS" "$LOGS"
# halt_on_error: the first report ends the program (and fails it); leaks are reported at exit.
export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:abort_on_error=0:strict_string_checks=1:detect_stack_use_after_return=1:check_initialization_order=1:suppressions=$ROOT/test/sanitize/asan.supp"
export LSAN_OPTIONS="suppressions=$ROOT/test/sanitize/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:suppressions=$ROOT/test/sanitize/ubsan.supp"
findings=0
for t in "${TESTS[@]}"; do
  bin="$WS/devel/lib/osm_graph_slam/$t"
  if [ ! -x "$bin" ]; then
    echo "[sanitize] $t: not built"
    failure_xml "$RESULTS/$t.xml" "$t" "not built"
    continue
  fi
  t0=$(date +%s)
  (cd "$ROOT" && timeout 1800 "$bin" --gtest_output="xml:$RESULTS/$t.xml") > "$LOGS/$t.log" 2>&1
  rc=$?
  reports=$(grep -cE "ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:" "$LOGS/$t.log")
  echo "[sanitize] $t: exit $rc, $reports sanitizer reports, $(( $(date +%s) - t0 )) s"
  if [ "$reports" -gt 0 ]; then
    findings=$((findings + reports))
    grep -E "ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:|^    #[0-9] " "$LOGS/$t.log" | head -12
  fi
  if [ $rc -ne 0 ]; then
    # A program that passed its cases but failed at exit (a leak report, a crash in teardown) or
    # died before writing results still fails.
    failure_xml "$RESULTS/${t}_exit.xml" "${t}_exit" "exit code $rc, $reports sanitizer reports (log $LOGS/$t.log)"
  fi
done

# The rostests: the Debian `nodelet` manager is not instrumented, so the ASan runtime is preloaded
# into it alone (launch arg manager_prefix); the test nodes are instrumented builds. Leak checks
# stay with the gtests: the manager is stopped by SIGINT and ROS's own teardown would flood them.
LIBASAN="$(g++ -print-file-name=libasan.so)"
for r in "${ROSTESTS[@]}"; do
  name="${r%.test}"
  reports_dir="$LOGS/${name}_sanitizer"
  mkdir -p "$reports_dir"
  t0=$(date +%s)
  (
    set +u  # the Debian catkin profile scripts read unset variables
    # shellcheck disable=SC1091
    source "$WS/devel/setup.bash"
    export ROS_MASTER_URI="http://127.0.0.1:${OGS_TEST_ROS_PORT:-22423}"
    export ROS_HOME="$WS/ros_home_sanitize"
    rm -rf "$ROS_HOME/test_results"
    export ASAN_OPTIONS="detect_leaks=0:halt_on_error=1:log_path=$reports_dir/asan:suppressions=$ROOT/test/sanitize/asan.supp"
    export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:log_path=$reports_dir/ubsan:suppressions=$ROOT/test/sanitize/ubsan.supp"
    cd "$ROOT" && timeout 1800 rostest --text osm_graph_slam "$r" \
      manager_prefix:="env LD_PRELOAD=$LIBASAN"
    mkdir -p "$RESULTS/rostest_$name"
    cp "$ROS_HOME"/test_results/osm_graph_slam/*.xml "$RESULTS/rostest_$name/" 2>/dev/null
  ) > "$LOGS/$name.log" 2>&1
  if ! ls "$RESULTS/rostest_$name"/*.xml > /dev/null 2>&1; then
    failure_xml "$RESULTS/rostest_${name}_results.xml" "$name" "no results (log $LOGS/$name.log)"
  fi
  reports=$(cat "$reports_dir"/* 2>/dev/null | grep -cE "ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:")
  echo "[sanitize] rostest $r: $(grep -cE '^\[ +OK \]' "$LOGS/$name.log") cases passed, $reports sanitizer reports, $(( $(date +%s) - t0 )) s"
  if [ "$reports" -gt 0 ]; then
    findings=$((findings + reports))
    cat "$reports_dir"/* | grep -E "ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:|^    #[0-9] " | head -12
    failure_xml "$RESULTS/rostest_${name}_sanitizer.xml" "${name}_sanitizer" "$reports sanitizer reports ($reports_dir)"
  fi
done
END=$(date +%s)
echo "[sanitize] tests took $((END - BUILT)) s; total $((END - START)) s; sanitizer reports: $findings"
python3 "$ROOT/scripts/test_summary.py" "$RESULTS" --build-status "$build_status"

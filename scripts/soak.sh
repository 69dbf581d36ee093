#!/usr/bin/env bash
# Soak test (issue 22): the ROS system on a looped simulated drive; see scripts/soak.py.
#   scripts/soak.sh --minutes 60 [--out DIR] [--sim-dir DIR] [--length M] [--rate R] ...
export PATH=/usr/bin:/bin:$PATH  # pyenv's python3 breaks the ROS tools
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$ROOT/build_ws/devel/setup.bash" || { echo "soak: build first (scripts/setup.sh)"; exit 1; }
exec /usr/bin/python3 "$ROOT/scripts/soak.py" "$@"

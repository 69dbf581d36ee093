#!/usr/bin/env bash
# The main job. Until the full pipeline lands, it runs the LiDAR front-end on the real scans of
# ../shared/data and says what it needs when they are absent.
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
echo "[demo] the front-end demo is not available in this build yet" >&2
exit 1

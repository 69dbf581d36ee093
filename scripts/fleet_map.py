#!/usr/bin/python3
"""Many drives, one map: offline_slam on every drive (simulated drives through one world, or
KITTI raw folders) as tasks on a Dask cluster, then merge_sessions over their dumps into one map.

    scripts/fleet_map.py --simulate 6 --world-seed 3 --prior-seed 7 --length 600 --out /tmp/fleet
    scripts/fleet_map.py --drives-from /data/2011_09_26 --osm city.osm --config config/kitti.yaml --out OUT
    scripts/fleet_map.py --simulate 2 --world-seed 3 --prior-seed 7 --dumps OLD/drives/*/slam/dump --out NEW
    scripts/fleet_map.py --scheduler tcp://10.0.0.5:8786 --simulate 20 --world-seed 3 --prior-seed 7 --out /shared/fleet

Progress while it runs, a summary at the end (also OUT/fleet_summary.json); exit status 0 when a
map was made (also from some sessions only), 1 when none could be, 2 for bad input. The code is
in the package fleet/ beside this script; doc/fleet.md describes it. Needs python3-distributed.
"""
import os
import sys

# The packages (fleet, drive_matrix) live beside this script; a tool that loads this file by
# path has not put the folder on the module path.
HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

from fleet.cli import build_parser, main  # noqa: E402  (needs the path above)

__all__ = ["build_parser", "main"]

if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/python3
"""The drive matrix: every accuracy number over many simulated drives instead of one.

For each drive (a world, seed, length, prior model, sensor, GNSS mode, manoeuvres and dropped
scans) it runs

    simulate_urban -> offline_slam (with the OSM prior) -> offline_slam --no-osm (the GNSS
    baseline) -> offline_slam --no-osm --gnss origin (odometry + loops) -> evaluate_slam --json

in a folder of its own named by the drive's parameters, collects one row per drive, prints a
fixed-width table with the median and worst of each column, and writes matrix.json. Finished
drives (result.json) are not run again. doc/matrix.md describes presets, axes and columns.

    scripts/slam_matrix.py --preset quick
    scripts/slam_matrix.py --preset default --jobs 2
    scripts/slam_matrix.py --preset default --executor dask --jobs 2      (or --scheduler tcp://HOST:8786)
    scripts/slam_matrix.py --preset default --check --max-ate-ratio 1.0 --min-coverage 0.95
    scripts/slam_matrix.py --world city --seed 1,2 --length 300 --prior-model global --list

The code is in the package drive_matrix/ beside this script (its __init__.py lists the modules).
Python 3 standard library only (the Dask executor: python3-distributed, doc/fleet.md).
"""
import os
import sys

# The package lives beside this script; a test or tool that loads this file by path has not
# put the folder on the module path.
HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:
    sys.path.insert(0, HERE)

from drive_matrix.cli import build_parser, main  # noqa: E402  (needs the path above)

__all__ = ["build_parser", "main"]

if __name__ == "__main__":
    sys.exit(main())

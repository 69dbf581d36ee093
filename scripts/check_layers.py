#!/usr/bin/env python3
"""Checks that every folder of the code base includes only the folders its layer may use.

The table below is the layer table of doc/architecture.md. A folder's headers
(include/osm_graph_slam/<folder>/) and sources (src/<folder>/) may include headers of the
folders listed for it, and of no other: a new tie that runs back up (say localization/ using
slam/) fails the build's configure step (CMakeLists.txt runs this script) and the Python tests.

    scripts/check_layers.py [ROOT]     exit 0 when every include is allowed, else 1 with a list
"""
import os
import re
import sys

CORE_STAGES = ["common", "cloud", "registration", "graph", "lines", "osm", "io", "landmarks",
               "loop", "odometry", "radar", "localization", "multi_cue", "visual",
               "inertial"]

# folder -> the folders it may include (besides itself)
ALLOWED = {
    "common": [],
    "cloud": ["common"],
    "registration": ["common", "cloud"],
    "graph": ["common"],
    "lines": ["common", "cloud"],
    "osm": ["common", "lines"],
    "io": ["common", "cloud", "osm"],
    "landmarks": ["common", "cloud"],
    "loop": ["common", "cloud", "registration", "landmarks"],
    "odometry": ["common", "cloud", "registration", "multi_cue"],
    "multi_cue": ["common", "cloud", "registration"],
    "visual": ["common"],
    "inertial": ["common"],
    "radar": ["common", "graph", "io", "loop", "osm"],
    "localization": ["common", "cloud", "graph", "io", "landmarks", "lines", "loop", "osm",
                     "registration"],
    "slam": CORE_STAGES,
    "eval": CORE_STAGES + ["slam"],
    "sim": CORE_STAGES,
    "ros": CORE_STAGES + ["slam"],
    "drive_io": CORE_STAGES + ["slam", "ros"],
    "nodelets": CORE_STAGES + ["slam", "ros"],
    "tools": CORE_STAGES + ["slam", "ros", "drive_io", "eval", "sim"],
}

INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]osm_graph_slam/([a-z_0-9]+)/')


def folder_files(root, folder):
    for base in (os.path.join(root, "include", "osm_graph_slam", folder),
                 os.path.join(root, "src", folder)):
        for dirpath, _, names in os.walk(base):
            for name in sorted(names):
                if name.endswith((".h", ".hpp", ".cpp")):
                    yield os.path.join(dirpath, name)


def violations(root):
    """(file, line number, included folder) of every include its folder's layer may not use;
    and the folders found on disk that the table does not know."""
    found = []
    folders = set()
    for top in (os.path.join(root, "src"), os.path.join(root, "include", "osm_graph_slam")):
        if os.path.isdir(top):
            folders.update(d for d in os.listdir(top) if os.path.isdir(os.path.join(top, d)))
    unknown = sorted(folders - set(ALLOWED))
    for folder in sorted(set(ALLOWED) & folders):
        allowed = set(ALLOWED[folder]) | {folder}
        for path in folder_files(root, folder):
            with open(path, encoding="utf-8", errors="replace") as f:
                for number, line in enumerate(f, 1):
                    m = INCLUDE.match(line)
                    if m and m.group(1) not in allowed and m.group(1) in ALLOWED:
                        found.append((os.path.relpath(path, root), number, m.group(1)))
    return found, unknown


def main(argv):
    root = argv[1] if len(argv) > 1 else os.path.join(os.path.dirname(__file__), "..")
    found, unknown = violations(os.path.abspath(root))
    for path, number, target in found:
        print(f"{path}:{number}: includes {target}/, which its layer may not use "
              f"(scripts/check_layers.py, doc/architecture.md)")
    for folder in unknown:
        print(f"folder '{folder}' is not in the layer table of scripts/check_layers.py")
    return 1 if found or unknown else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

#!/usr/bin/python3
"""Consensus of a simulated fleet (issue 53; doc/fleet.md "Consensus"): merges the first N
drives of a fleet_map.py --simulate run for each N and scores every merged map against the
simulator's truth (observed buildings' corner and shape error, each drive's ATE merged against
alone, inter-session loops: false ones and the recall of cross-drive revisits).

  scripts/fleet_consensus.py --fleet OUT [--counts 1,2,4,8,16] [--bin DIR] [--config FILE]

Writes OUT/consensus/n<N>/ (the merged maps), OUT/consensus/consensus.json and
OUT/consensus/error_vs_drives.png, and prints the table."""
import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from fleet.consensus import ConsensusError, evaluate_count, fleet_drives, format_table, plot  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fleet", required=True, help="a fleet_map.py --simulate output folder")
    ap.add_argument("--counts", default="1,2,4,8,16", help="numbers of drives to merge (default %(default)s)")
    ap.add_argument("--bin", default=os.path.join(REPO, "build_ws", "devel", "lib", "osm_graph_slam"))
    ap.add_argument("--config", default=os.path.join(REPO, "config", "sim.yaml"))
    args = ap.parse_args(argv)
    try:
        counts = sorted({int(c) for c in args.counts.split(",") if c.strip()})
        drives = fleet_drives(args.fleet)
        counts = [n for n in counts if 1 <= n <= len(drives)]
        if not counts:
            raise ConsensusError("%d finished drives in %s: no count of --counts fits" % (len(drives), args.fleet))
        rows = []
        for n in counts:
            print("[consensus] merging %d drive(s)" % n, flush=True)
            rows.append(evaluate_count(args.fleet, drives, n, args.bin, args.config))
    except (ConsensusError, OSError, ValueError) as e:
        print("fleet_consensus: %s" % e, file=sys.stderr)
        return 1
    out = os.path.join(args.fleet, "consensus")
    with open(os.path.join(out, "consensus.json"), "w") as f:
        json.dump(rows, f, indent=1)
    plot(rows, os.path.join(out, "error_vs_drives.png"))
    print(format_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""fleet_map.py's command line: the options, the run, OUT/fleet_summary.json and the exit
status (0 when a map was made, even from some sessions only; 1 when no map could be made;
2 for bad input; 130 when interrupted)."""
import argparse
import json
import os
import shlex
import sys
import time

from drive_matrix.cli import DEFAULT_SIM_ARGS
from drive_matrix.drives import REPO
from drive_matrix.files import unwritable, write_atomically

from . import cluster
from .plan import FleetError, given_dumps, kitti_jobs, make_names_unique, simulated_jobs, split_finished
from .report import fleet_document, mark_unreadable_sessions, summary_lines
from .run import run_fleet
from .tasks import Settings


def positive_number_text(text):
    """The text as given (passed on to merge_sessions unchanged), once it is a positive number."""
    try:
        ok = float(text) > 0
    except ValueError:
        ok = False
    if not ok:
        raise argparse.ArgumentTypeError("a positive number of metres, not %r" % text)
    return text


def build_parser():
    ap = argparse.ArgumentParser(
        description="Many drives, one map: offline_slam on every drive as a Dask task (simulated "
                    "drives through one world, or KITTI raw folders), then merge_sessions over "
                    "their dumps and any given ones. See doc/fleet.md.")
    src = ap.add_argument_group("sessions (any of them, at least one)")
    src.add_argument("--drives-from", nargs="+", default=[], metavar="DIR",
                     help="KITTI raw drives: a *_drive_NNNN_sync folder, or a folder with them one or two levels down")
    src.add_argument("--simulate", type=int, metavar="N", help="N simulated drives through one world")
    src.add_argument("--dumps", nargs="+", default=[], metavar="DIR",
                     help="dumps made before (offline_slam --dump): merged as they are, not run again")
    sim = ap.add_argument_group("simulated drives (--simulate)")
    sim.add_argument("--world-seed", type=int, metavar="W", help="the one world of every drive (required)")
    sim.add_argument("--prior-seed", type=int, metavar="P", help="the one OSM prior of every drive (required)")
    sim.add_argument("--first-seed", type=int, default=1, metavar="S",
                     help="route seeds S, S+1, ... and start days 0, 1, ... (default %(default)s)")
    sim.add_argument("--length", type=float, metavar="M", help="route length [m] (default: simulate_urban's)")
    sim.add_argument("--depot", metavar="X,Y", default="0,0",
                     help="every route starts at the junction nearest to this ENU point [m], so that "
                          "the drives share streets as a fleet from one garage does; 'none': a "
                          "junction drawn from each drive's seed (default %(default)s)")
    sim.add_argument("--sim-args", default=DEFAULT_SIM_ARGS,
                     help="extra simulate_urban options for every drive (default: '%(default)s')")
    ap.add_argument("--osm", metavar="FILE",
                    help="the OSM prior for --drives-from drives (default: simulate_urban's prior.osm "
                         "beside the drive if any, else offline_slam --no-osm)")
    ap.add_argument("--out", required=True, metavar="OUT", help="drives/<name>/, merged/, fleet_summary.json")
    ap.add_argument("--bin", default=os.path.join(REPO, "build_ws", "devel", "lib", "osm_graph_slam"),
                    help="the C++ tools' folder (default: %(default)s)")
    ap.add_argument("--config", default=os.path.join(REPO, "config", "sim.yaml"),
                    help="offline_slam --config (default: %(default)s; config/kitti.yaml for real KITTI drives)")
    ap.add_argument("--tile-size", type=positive_number_text, metavar="M", help="merge_sessions --tile-size [m]")
    ap.add_argument("--step-timeout", type=float, metavar="S", help="stop a tool after S seconds (default: no limit)")
    ap.add_argument("--force", action="store_true", help="run every drive again, also those with a done.json")
    where = ap.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="use the running Dask cluster at ADDRESS (tcp://host:8786) as it is")
    where.add_argument("--workers", type=int, metavar="N",
                       help="worker processes of the local cluster (default: one per core: %d here)"
                       % cluster.default_workers())
    return ap


def main(argv=None, log=None, stream=None):
    log = log or (lambda text: print(text, flush=True))
    args = build_parser().parse_args(argv)
    try:
        return _main(args, log, stream)
    except FleetError as e:
        print("fleet_map: %s" % e, file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\nfleet_map: interrupted; finished drives keep their done.json (run the same command "
              "to go on)", file=sys.stderr)
        return 130


def _main(args, log, stream):
    t0 = time.monotonic()
    jobs, dumps = _sessions(args)
    out = os.path.abspath(args.out)
    problem = unwritable(out)
    if problem:
        raise FleetError("cannot write the output folder %s: %s" % (out, problem))
    _require_tools(args, jobs)
    to_run, finished = split_finished(jobs, out, args.force)
    settings = Settings(args.bin, args.config, out, args.step_timeout)
    client, local = cluster.connect(args.scheduler, args.workers)
    try:
        sessions, merge = run_fleet(client, jobs, to_run, finished, dumps, settings, args.tile_size,
                                    stream, log)
    finally:
        cluster.close(client, local)
    mark_unreadable_sessions(sessions, merge)
    doc = fleet_document(sessions, merge, time.monotonic() - t0, out, sys.argv)
    for line in summary_lines(doc):
        log(line)
    path = os.path.join(out, "fleet_summary.json")
    write_atomically(path, json.dumps(doc, indent=2) + "\n")
    log("[fleet] summary in %s" % path)
    return 0 if doc["map"]["made"] else 1


def _sessions(args):
    """(drive jobs, given dumps), names unique; FleetError for bad input."""
    if args.workers is not None and args.workers < 1:
        raise FleetError("--workers must be at least 1")
    jobs = kitti_jobs(args.drives_from, os.path.abspath(args.osm) if args.osm else None)
    if args.simulate is not None:
        jobs += _simulated(args)
    dumps = given_dumps(args.dumps)
    if not jobs and not dumps:
        raise FleetError("nothing to map: give --drives-from, --simulate or --dumps")
    make_names_unique(jobs + dumps)
    return jobs, dumps


def _simulated(args):
    if args.simulate < 1:
        raise FleetError("--simulate takes the number of drives (at least 1)")
    if args.world_seed is None or args.prior_seed is None:
        raise FleetError("--simulate needs --world-seed and --prior-seed (one world, one prior for every drive)")
    try:
        sim_args = shlex.split(args.sim_args)
    except ValueError as e:
        raise FleetError("--sim-args: %s" % e) from None
    length = args.length
    if length is not None and length == int(length):
        length = int(length)  # "--length 300", as the matrix passes it
    depot = [] if args.depot == "none" else ["--route-start", args.depot]
    return simulated_jobs(args.simulate, args.world_seed, args.prior_seed, length, depot + sim_args,
                          args.first_seed)


def _require_tools(args, jobs):
    needed = ["merge_sessions"]
    if jobs:
        needed.append("offline_slam")
    if any(j.simulated for j in jobs):
        needed.append("simulate_urban")
    missing = [t for t in needed if not os.access(os.path.join(args.bin, t), os.X_OK)]
    if missing:
        raise FleetError("%s missing in %s: build first (scripts/setup.sh) or give --bin"
                         % (", ".join(missing), args.bin))
    if jobs and not os.path.isfile(args.config):
        raise FleetError("offline_slam config %s missing" % args.config)
    if args.osm and not os.path.isfile(args.osm):
        raise FleetError("--osm %s: no such file" % args.osm)


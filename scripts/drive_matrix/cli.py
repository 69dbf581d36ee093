"""The command line: options, the run, the table, matrix.json and the exit status (0; 1 when
--check fails; 2 for bad input; 130 when interrupted)."""
import argparse
import json
import os
import shlex
import sys
import time

from .drives import GNSS_MODES, KARLSRUHE, PRIOR_MODELS, REPO, SENSORS, MatrixError
from .files import unwritable, write_atomically
from .grid import PRESETS, axes_from_args, build_grid
from .mode_summary import format_mode_summary, summarize_modes
from .one_drive import drive_row, world_problem
from .scheduler import EXECUTORS, estimate_text, plan, print_flushed, run_matrix
from .table import LIMITS, check_rows, format_table, is_ok, summarize, worst_drive
from .tools import TOOLS, Context, evaluate_options

DEFAULT_SIM_ARGS = "--motion-distortion --kitti-calibration-error"  # as scripts/demo.sh
AXIS_OPTIONS = ("world", "osm", "seed", "length", "prior_model", "sensor", "gnss", "manoeuvres",
                "drop_scans", "dropout_burst", "map_shift")


def build_parser():
    ap = argparse.ArgumentParser(
        description="Runs simulate_urban -> offline_slam (OSM) -> offline_slam --no-osm (GNSS) -> "
                    "offline_slam --no-osm --gnss origin (odometry + loops) -> evaluate_slam over a "
                    "matrix of drives; table, summary, matrix.json. See doc/matrix.md.")
    ap.add_argument("--preset", choices=sorted(PRESETS), help="a predefined matrix; explicit axes replace its axes")
    g = ap.add_argument_group("axes (repeatable or comma-separated; without --preset: their product)")
    g.add_argument("--world", action="append", metavar="W",
                   help="city (the procedural city), karlsruhe (%s) or [LABEL=]FILE.osm" % KARLSRUHE)
    g.add_argument("--osm", action="append", metavar="FILE", help="an OSM extract as a world ([LABEL=]FILE)")
    g.add_argument("--seed", action="append", metavar="N")
    g.add_argument("--length", action="append", metavar="M", help="route length [m]")
    g.add_argument("--prior-model", action="append", metavar="P", help="|".join(PRIOR_MODELS))
    g.add_argument("--sensor", action="append", metavar="S", help="|".join(SENSORS))
    g.add_argument("--gnss", action="append", metavar="G",
                   help="|".join(GNSS_MODES) + ": noisy (default), rtk (simulate_urban --rtk), canyon "
                        "(--gnss-model canyon), origin (noisy fixes, SLAM runs with --gnss origin); "
                        "canyon and origin add --downtown on the procedural city")
    g.add_argument("--manoeuvres", action="append", metavar="LIST",
                   help="one simulate_urban --manoeuvres value per option (none, all, sharp_turn,stop ...)")
    g.add_argument("--drop-scans", action="append", metavar="F", help="fraction of scans dropped")
    g.add_argument("--dropout-burst", action="append", metavar="N[@T]",
                   help="one burst of N consecutive missing scans (at T s); 0 = none")
    g.add_argument("--map-shift", action="append", metavar="M",
                   help="the 'global' and 'mixed' prior models' common map shift [m], fixed "
                        "(simulate_urban --prior-global-offset M,M); 0 = uniform in 1-3 m")
    ap.add_argument("--sim-args", default=DEFAULT_SIM_ARGS,
                    help="extra simulate_urban options for every drive (default: '%(default)s')")
    ap.add_argument("--bin", default=os.path.join(REPO, "build_ws", "devel", "lib", "osm_graph_slam"),
                    help="the tools' folder (default: %(default)s)")
    ap.add_argument("--config", default=os.path.join(REPO, "config", "sim.yaml"),
                    help="offline_slam --config (default: %(default)s)")
    ap.add_argument("--out", default=os.path.join(REPO, "build_ws", "matrix"), help="default: %(default)s")
    ap.add_argument("--jobs", type=int, default=1, help="drives at a time (each tool uses both cores; default 1)")
    ap.add_argument("--executor", choices=EXECUTORS, default="threads",
                    help="threads (default) or dask: the drives as tasks on a local Dask cluster of "
                         "--jobs worker processes (doc/fleet.md; needs python3-distributed)")
    ap.add_argument("--scheduler", metavar="ADDRESS",
                    help="run the drives on the Dask cluster at ADDRESS (tcp://host:8786) as it is "
                         "(implies --executor dask; --jobs is then the cluster's)")
    ap.add_argument("--keep", action="store_true", help="keep the simulated scans (velodyne_points)")
    ap.add_argument("--dump", action="store_true",
                    help="keep the back-end's inputs (slam_*/dump, without clouds) for --replay")
    ap.add_argument("--replay", metavar="FROM",
                    help="no simulation, no front-end: replay_backend on FROM/<drive>/slam_*/dump "
                         "(a matrix run with --dump) with --set, evaluated as usual (seconds per drive)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="with --replay: a graph_backend parameter for every run (replay_backend --set)")
    ap.add_argument("--force", action="store_true", help="run drives again even if they have a result.json")
    ap.add_argument("--retry-failed", action="store_true", help="run drives again whose stored status is not ok")
    ap.add_argument("--step-timeout", type=float, default=None, metavar="S",
                    help="stop a step after S seconds (default: no limit)")
    ap.add_argument("--list", action="store_true", help="print the drives and the time estimate; run nothing")
    ap.add_argument("--no-run", action="store_true", help="only the table of the drives already finished")
    c = ap.add_argument_group("check (--check: exit 1 if a drive violates a limit or did not finish)")
    c.add_argument("--check", action="store_true")
    c.add_argument("--max-ate-ratio", type=float, metavar="R", help="ATE with OSM / ATE without")
    c.add_argument("--max-rpe-ratio", type=float, metavar="R", help="t-RPE with OSM / t-RPE without")
    c.add_argument("--min-coverage", type=float, metavar="F", help="fraction of the drive's time estimated")
    c.add_argument("--max-false-loops", type=int, metavar="N")
    c.add_argument("--max-building-error", type=float, metavar="M", help="corrected mean corner error [m]")
    return ap


def main(argv=None, log=print_flushed):
    args = build_parser().parse_args(argv)
    try:
        return _main(args, log)
    except MatrixError as e:
        print("slam_matrix: %s" % e, file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\nslam_matrix: interrupted; finished drives keep their result.json (run the same "
              "command to resume)", file=sys.stderr)
        return 130


def _main(args, log):
    drives, sim_args = _drives_and_sim_args(args)
    if args.list:
        _print_drive_list(drives, sim_args, args.jobs, log)
        return 0
    out = os.path.abspath(args.out)
    problem = unwritable(out)
    if problem:
        raise MatrixError("cannot write the output folder %s: %s" % (out, problem))

    to_run, stored = plan(drives, out, args.force, args.retry_failed)
    if args.no_run:
        to_run = []
    log("[matrix] %s; %d finished before, %d to run -> %s" % (estimate_text(drives, args.jobs),
                                                              len(stored), len(to_run), out))
    results = _run_drives(args, drives, to_run, out, sim_args, log) if to_run else {}
    rows = _rows_in_table_order(drives, results, stored, args.no_run)
    summary, by_gnss = summarize(rows), summarize_modes(rows)
    worst, why = worst_drive(rows)
    _print_table(rows, summary, worst, why, log)
    for line in format_mode_summary(by_gnss):
        log(line)

    limits = {a: getattr(args, a) for a, _, _, _ in LIMITS}
    violations = check_rows(rows, limits) if args.check else []
    doc = _matrix_document(args, sim_args, rows, summary, worst, why)
    doc["summary_by_gnss"] = by_gnss
    if args.check:
        doc["check"] = {"limits": limits, "violations": violations}
    _write_matrix_json(out, doc, log)
    if args.check:
        return _check_status(rows, limits, violations, log)
    return 0


def _drives_and_sim_args(args):
    """The matrix's drives and the simulator's extra options; MatrixError for bad input."""
    if args.jobs < 1:
        raise MatrixError("--jobs must be at least 1")
    if not args.preset and not any(getattr(args, a) for a in AXIS_OPTIONS):
        raise MatrixError("give --preset quick|default|stress or the axes (--world, --seed, --length, ...)")
    drives = build_grid(*axes_from_args(args))
    try:
        sim_args = shlex.split(args.sim_args)
    except ValueError as e:
        raise MatrixError("--sim-args: %s" % e) from None
    return drives, sim_args


def _print_drive_list(drives, sim_args, jobs, log):
    for i, d in enumerate(drives, 1):
        log("%3d %-60s %5.0f scans  %4.1f min  simulate_urban %s" % (
            i, d.name, d.estimated_scans(), d.estimated_seconds() / 60, " ".join(d.sim_flags() + sim_args)))
    log(estimate_text(drives, jobs))


def _run_drives(args, drives, to_run, out, sim_args, log):
    """{drive: row} of the drives run now. The tools must be there unless every drive to run has
    a bad world (those give their row without running anything)."""
    runnable = [d for d in to_run if not world_problem(d)]
    if runnable:
        _require_tools(args)
    ctx = Context(os.path.abspath(args.bin), os.path.abspath(args.config), out, sim_args, args.keep,
                  args.step_timeout, evaluate_options(args.bin) if runnable else (), args.dump,
                  os.path.abspath(args.replay) if args.replay else None, args.set)
    return run_matrix(drives, ctx, to_run, args.jobs, log=log, executor=args.executor,
                      scheduler=args.scheduler)


def _require_tools(args):
    tools = ("replay_backend", "evaluate_slam") if args.replay else TOOLS
    missing = [t for t in tools if not os.access(os.path.join(args.bin, t), os.X_OK)]
    if missing:
        raise MatrixError("%s missing in %s: build first (scripts/setup.sh) or give --bin"
                          % (", ".join(missing), args.bin))
    if not os.path.isfile(args.config):
        raise MatrixError("offline_slam config %s missing" % args.config)


def _rows_in_table_order(drives, results, stored, no_run):
    """One row per drive: run now, else stored, else a row saying why it has no numbers."""
    rows = []
    for d in drives:
        row = results.get(d) or stored.get(d)
        if row is None:
            row = drive_row(d, "not run" if no_run else "interrupted")
        rows.append(row)
    return rows


def _print_table(rows, summary, worst, why, log):
    log("")
    log(format_table(rows, summary))
    log("")
    failed = [r for r in rows if not is_ok(r)]
    log("[matrix] %d drives, %d ok, %d not ok; median and worst over the ok drives "
        "(worst = max, except cover/recall/sc/s = min)" % (len(rows), len(rows) - len(failed), len(failed)))
    if worst:
        log("[matrix] worst drive: %s: %s" % (worst, why))
    if failed:
        log("[matrix] not ok (status column; logs in <drive>/logs): %s" % ", ".join(r["drive"] for r in failed))


RUNS_DOC = {
    "slam_osm": "offline_slam --osm sim/prior.osm (on 'origin' drives with --gnss origin): everything (ATE_osm)",
    "slam_no_osm": "offline_slam --no-osm: the GNSS baseline, evaluate_slam label 'gnss' (ATE_gns); "
                   "on 'origin' drives with --gnss origin: odometry + loops, label 'odom+loops'",
    "slam_odom": "offline_slam --no-osm --gnss origin: odometry + loops (ATE_odo); not run on 'origin' "
                 "drives, whose slam_no_osm is that run (metrics odom_run)",
}


def _matrix_document(args, sim_args, rows, summary, worst, why):
    return {
        "generated": time.strftime("%Y-%m-%d %H:%M:%S"),
        "command": sys.argv,
        "preset": args.preset,
        "sim_args": sim_args,
        "runs": RUNS_DOC,
        "drives": rows,
        "summary": summary,
        "worst_drive": {"drive": worst, "why": why},
    }


def _write_matrix_json(out, doc, log):
    """Writes out/matrix.json; a failure is reported, not raised: the table was printed already."""
    path = os.path.join(out, "matrix.json")
    try:
        write_atomically(path, json.dumps(doc, indent=2) + "\n")
        log("[matrix] rows in %s; each drive's logs in %s/<drive>/logs" % (path, out))
    except OSError as e:
        log("[matrix] cannot write %s: %s" % (path, e.strerror or e))


def _check_status(rows, limits, violations, log):
    """--check's exit status: 1 when a drive violates a limit or did not finish. Without any
    limit only the drives that did not finish count."""
    if not any(v is not None for v in limits.values()):
        log("[matrix] check: no limit given (--max-ate-ratio, --max-rpe-ratio, --min-coverage, "
            "--max-false-loops, --max-building-error); only failed drives count")
        violations = ["%s: did not finish (%s)" % (r["drive"], r["status"]) for r in rows if not is_ok(r)]
    for v in violations:
        log("[matrix] CHECK FAILED: %s" % v)
    if violations:
        return 1
    log("[matrix] check passed (%d drives)" % len(rows))
    return 0

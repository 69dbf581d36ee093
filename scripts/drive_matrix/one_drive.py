"""Runs one drive in a folder of its own: simulate_urban and offline_slam with and without OSM
(or, with --replay, replay_backend on another matrix's dumps), then evaluate_slam; writes the
drive's result.json, which a later run reads instead of running the drive again."""
import json
import os
import re
import shutil
import time
import traceback

from .evaluation import BASELINE_LABEL, dig, parse_metrics
from .files import last_log_line, read_json, sorted_listdir, unwritable, write_atomically
from .ground_truth import first_fix, write_full_ground_truth
from .own_metrics import absolute_offset_metrics, orientation_metrics, own_coverage, read_tum_stamps
from .tools import StepFailed, Stopped


def drive_row(drive, status, metrics=None, steps=None):
    """One row of the table and of matrix.json: the drive's axes, its status and its numbers."""
    row = drive.axes()
    row["status"] = status
    row["metrics"] = metrics or {}
    row["step_seconds"] = steps or {}
    return row


def world_problem(drive):
    """The status of a drive whose OSM file cannot be read (it is not run), or None."""
    if drive.world.path is None:
        return None
    if not os.path.isfile(drive.world.path):
        return "error: world file missing: %s" % drive.world.path
    if not os.access(drive.world.path, os.R_OK):
        return "error: world file unreadable: %s" % drive.world.path
    return None


def rejected_flags_hint(drive, log_path):
    """simulate_urban prints its usage (status 2) for an option it does not know: today naming it
    ("unknown option '--x'"), older builds listing the options they know."""
    try:
        with open(log_path, errors="replace") as f:
            text = "".join(line for line in f if not line.startswith("$ "))  # not our command line
    except OSError:
        return None
    if "usage:" not in text:
        return None
    named = re.findall(r"unknown option '(--[\w-]+)'", text)
    if named:
        unknown = [f for f in drive.new_flags() if f in named]
    else:
        unknown = [f for f in drive.new_flags() if f.startswith("--") and f not in text]
    if unknown:
        return ("simulate: simulate_urban does not know %s (printed its usage; not built yet?)"
                % " ".join(unknown))
    return "simulate: simulate_urban rejected its arguments (printed its usage; see logs/simulate_urban.log)"


def run_drive(drive, ctx):
    """Runs one drive in ctx.out/<drive.name> and returns its row. Never raises for bad input or
    failing tools: the row's status says what went wrong."""
    problem = world_problem(drive)
    if problem:
        return drive_row(drive, problem)
    d = os.path.join(ctx.out, drive.name)
    logs = os.path.join(d, "logs")
    problem = unwritable(logs)
    if problem:
        return drive_row(drive, "error: cannot write %s: %s" % (d, problem))
    steps = {}
    try:
        return _run_drive_steps(drive, ctx, d, logs, steps)
    except Stopped:
        raise
    except StepFailed as e:
        status = "error: %s" % e
    except Exception as e:  # a bug or an unexpected file: one line in the table, details in the log
        status = "error: internal: %s: %s (details in logs/matrix.log)" % (type(e).__name__, e)
        try:
            with open(os.path.join(logs, "matrix.log"), "a") as f:
                f.write(traceback.format_exc())
        except OSError:
            pass
    row = drive_row(drive, status, steps=steps)
    _finish_drive(ctx, d, row)
    return row


def _clean(d):
    """Removes an earlier run's files, so that none of them is read as this run's."""
    if os.path.islink(os.path.join(d, "sim")):  # --replay: the source's simulation
        os.remove(os.path.join(d, "sim"))
    for name in ("sim", "slam_osm", "slam_no_osm"):
        shutil.rmtree(os.path.join(d, name), ignore_errors=True)
    for name in ("evaluation.json", "ground_truth_tum.txt", "result.json"):
        try:
            os.remove(os.path.join(d, name))
        except FileNotFoundError:
            pass
    for name in os.listdir(os.path.join(d, "logs")):
        try:
            os.remove(os.path.join(d, "logs", name))
        except OSError:
            pass


def _timed(steps, name, fn):
    t0 = time.monotonic()
    fn()
    steps[name] = round(time.monotonic() - t0, 1)


def _run_drive_steps(drive, ctx, d, logs, steps):
    _clean(d)
    write_atomically(os.path.join(d, "drive.json"), json.dumps(drive.axes(), indent=2) + "\n")
    if ctx.replay_from:
        sim, drive_dir = _replay_backends(drive, ctx, d, logs, steps)
    else:
        sim, drive_dir = _simulate_and_run_slam(drive, ctx, d, logs, steps)
    return _evaluate_drive(drive, ctx, d, logs, steps, sim, drive_dir)


def _find_drive_dir(sim):
    """simulate_urban's KITTI raw drive folder (sim/<date>/<date>_drive_NNNN_sync), or None."""
    drives = sorted(p for p in (os.path.join(sim, a, b) for a in sorted_listdir(sim)
                                for b in sorted_listdir(os.path.join(sim, a)))
                    if re.search(r"_drive_\d+_sync$", p) and os.path.isdir(p))
    return drives[0] if drives else None


REPLAY_COPIED = {"slam_osm": ("ground_truth_scans_tum.txt", "ground_truth_tum.txt", "loops.txt", "timing.json"),
                 "slam_no_osm": ("ground_truth_tum.txt", "timing.json")}


def _replay_backends(drive, ctx, d, logs, steps):
    """--replay FROM: the same drive's back-end inputs (FROM/<drive>/slam_*/dump, written with
    --dump) through replay_backend with --set; the front-end's files (truth, loops, timing) and
    the simulation are taken from FROM unchanged."""
    src = os.path.join(ctx.replay_from, drive.name)
    sim = os.path.join(d, "sim")
    if not os.path.isdir(os.path.join(src, "sim")):
        raise StepFailed("replay: %s has no sim folder (run the matrix there first)" % src)
    os.symlink(os.path.join(os.path.abspath(src), "sim"), sim)
    drive_dir = _find_drive_dir(sim)
    if drive_dir is None:
        raise StepFailed("replay: no drive folder in %s" % sim)
    for run, extra in (("slam_osm", []), ("slam_no_osm", ["--no-osm"])):
        dump = os.path.join(src, run, "dump")
        if not os.path.isfile(os.path.join(dump, "keyframes.csv")):
            raise StepFailed("replay: %s missing (run the matrix there with --dump)" % dump)
        out = os.path.join(d, run)
        sets = [a for kv in ctx.replay_sets for a in ("--set", kv)]
        _timed(steps, "replay_" + run, lambda: ctx.run(
            "replay_backend (%s)" % run, [ctx.tool("replay_backend"), "--dump", dump, "--output", out,
                                          "--config", ctx.config] + extra + sets,
            os.path.join(logs, "replay_%s.log" % run)))
        for name in REPLAY_COPIED[run]:
            if os.path.isfile(os.path.join(src, run, name)):
                shutil.copyfile(os.path.join(src, run, name), os.path.join(out, name))
    return sim, drive_dir


def _simulate_and_run_slam(drive, ctx, d, logs, steps):
    """simulate_urban, then offline_slam with the simulated OSM prior and with --no-osm (the
    baseline); returns (simulation folder, drive folder)."""
    sim = os.path.join(d, "sim")
    sim_log = os.path.join(logs, "simulate_urban.log")
    cmd = [ctx.tool("simulate_urban"), "--out", sim] + drive.sim_flags() + ctx.sim_args
    try:
        _timed(steps, "simulate", lambda: ctx.run("simulate", cmd, sim_log))
    except StepFailed:
        hint = rejected_flags_hint(drive, sim_log)
        if hint:
            raise StepFailed(hint) from None
        raise
    drive_dir = _find_drive_dir(sim)
    if drive_dir is None:
        raise StepFailed("simulate: no drive folder in %s (%s)" % (sim, last_log_line(sim_log) or "empty log"))
    prior = os.path.join(sim, "prior.osm")

    common = [ctx.tool("offline_slam"), "--kitti-raw", drive_dir, "--config", ctx.config]
    osm_out, no_osm_out = os.path.join(d, "slam_osm"), os.path.join(d, "slam_no_osm")

    def dump(run_out):  # the back-end's inputs, for replay_backend (--replay)
        return ["--dump", os.path.join(run_out, "dump"), "--dump-without-clouds"] if ctx.dump else []

    _timed(steps, "offline_slam_osm", lambda: ctx.run(
        "offline_slam (with OSM)", common + ["--osm", prior, "--output", osm_out] + dump(osm_out),
        os.path.join(logs, "offline_slam_osm.log")))
    _timed(steps, "offline_slam_no_osm", lambda: ctx.run(
        "offline_slam --no-osm", common + ["--no-osm", "--output", no_osm_out] + dump(no_osm_out),
        os.path.join(logs, "offline_slam_no_osm.log")))
    return sim, drive_dir


def _evaluate_drive(drive, ctx, d, logs, steps, sim, drive_dir):
    osm_out, no_osm_out = os.path.join(d, "slam_osm"), os.path.join(d, "slam_no_osm")
    notes = []
    gt = _whole_drive_ground_truth(d, sim, drive_dir, osm_out, notes)
    cmd = _evaluate_command(ctx, sim, drive_dir, osm_out, no_osm_out, gt)
    report = os.path.join(osm_out, "timing.json")
    evaluation = _run_evaluate(ctx, d, logs, steps, cmd, _newer_evaluate_options(ctx, osm_out, report), notes)
    metrics = _drive_metrics(evaluation, sim, drive_dir, osm_out, no_osm_out, gt, report)
    metrics["ground_truth"] = os.path.relpath(gt, d)
    if notes:
        metrics["notes"] = notes
    steps["total"] = round(sum(steps.values()), 1)
    row = drive_row(drive, "ok", metrics, steps)
    _finish_drive(ctx, d, row)
    return row


def _whole_drive_ground_truth(d, sim, drive_dir, osm_out, notes):
    """The ground truth of the whole drive, so that coverage can see where the estimate stops
    short: offline_slam's truth of every scan (newer builds), else the simulator's true poses
    moved into the map frame here, else offline_slam's truth of the keyframes (noted)."""
    gt = os.path.join(osm_out, "ground_truth_scans_tum.txt")
    if os.path.isfile(gt):
        return gt
    gt = os.path.join(d, "ground_truth_tum.txt")
    try:
        write_full_ground_truth(sim, drive_dir, gt)
    except (OSError, ValueError, KeyError, TypeError) as e:
        notes.append("ground truth of the keyframes only (slam_osm/ground_truth_tum.txt): %s" % e)
        gt = os.path.join(osm_out, "ground_truth_tum.txt")
    return gt


def _evaluate_command(ctx, sim, drive_dir, osm_out, no_osm_out, gt):
    fix = first_fix(drive_dir)  # the map frame's origin (the plots' buildings are projected there)
    if fix is None:
        raise StepFailed("evaluate: no OXTS record with a GNSS fix in %s/oxts/data" % drive_dir)
    origin = "%.9f,%.9f" % (fix[0], fix[1])
    return [ctx.tool("evaluate_slam"), "--estimate", os.path.join(osm_out, "trajectory_tum.txt"),
            "--ground-truth", gt, "--origin", origin,
            "--baseline", os.path.join(no_osm_out, "trajectory_tum.txt"), "--baseline-label", BASELINE_LABEL,
            "--buildings-true", os.path.join(sim, "buildings_true.geojson"),
            "--buildings-prior", os.path.join(sim, "prior.osm"),
            "--buildings-corrected", os.path.join(osm_out, "buildings_corrected.geojson")]


def _newer_evaluate_options(ctx, osm_out, report):
    """The newer options only when this evaluate_slam knows them and offline_slam wrote the files
    (a timing.json without "tracking" is from an older offline_slam)."""
    optional = []
    if "--run-report" in ctx.eval_options and isinstance(dig(read_json(report), "tracking"), dict):
        optional += ["--run-report", report]
    for name in ("loops.csv", "loops.txt"):
        if "--loops" in ctx.eval_options and os.path.isfile(os.path.join(osm_out, name)):
            optional += ["--loops", os.path.join(osm_out, name)]
            break
    return optional


def _run_evaluate(ctx, d, logs, steps, cmd, optional, notes):
    """evaluate_slam --json into d/evaluation.json; the document. If it fails with the newer
    options it runs once more without them (noted), so that a mismatch of the tools' versions
    still gives the older numbers."""
    eval_log = os.path.join(logs, "evaluate_slam.log")
    evaluation_path = os.path.join(d, "evaluation.json")
    try:
        _timed(steps, "evaluate", lambda: ctx.run("evaluate", cmd + optional + ["--json"], eval_log,
                                                  evaluation_path))
    except StepFailed as e:
        if not optional:
            raise
        notes.append("evaluate_slam failed with %s (%s); evaluated without them" % (" ".join(optional), e))
        _timed(steps, "evaluate", lambda: ctx.run("evaluate (without --run-report/--loops)", cmd + ["--json"],
                                                  eval_log, evaluation_path))
    evaluation = read_json(evaluation_path)
    if not isinstance(evaluation, dict):
        raise StepFailed("evaluate: evaluation.json is not JSON: %s" % (last_log_line(evaluation_path) or "empty"))
    return evaluation


def _drive_metrics(evaluation, sim, drive_dir, osm_out, no_osm_out, gt, report):
    """evaluate_slam's numbers with the matrix's own: coverage, orientation, absolute offsets."""
    try:
        coverage = own_coverage(read_tum_stamps(os.path.join(osm_out, "trajectory_tum.txt")),
                                read_tum_stamps(gt))
    except (OSError, ValueError):
        coverage = None
    metrics = parse_metrics(evaluation, read_json(report), read_json(os.path.join(no_osm_out, "timing.json")),
                            read_json(os.path.join(sim, "sim_info.json")), coverage)
    metrics["own_coverage"] = coverage
    metrics.update(orientation_metrics(osm_out, no_osm_out))
    metrics.update(absolute_offset_metrics(sim, drive_dir, os.path.join(osm_out, "buildings_corrected.geojson")))
    return metrics


def _finish_drive(ctx, d, row):
    """Deletes the simulated scans (GBs for 1.5 km) unless --keep; writes result.json."""
    # --replay links the source's simulation: never delete in there (its drives may be running).
    if not ctx.keep and not os.path.islink(os.path.join(d, "sim")):
        sim = os.path.join(d, "sim")
        for a in sorted_listdir(sim):
            for b in sorted_listdir(os.path.join(sim, a)):
                shutil.rmtree(os.path.join(sim, a, b, "velodyne_points"), ignore_errors=True)
    row["finished"] = time.strftime("%Y-%m-%d %H:%M:%S")
    try:
        write_atomically(os.path.join(d, "result.json"), json.dumps(row, indent=2) + "\n")
    except OSError as e:
        row["status"] += " (result.json not written: %s)" % (e.strerror or e)


def load_result(drive, out):
    """The stored row of a finished drive, or None."""
    row = read_json(os.path.join(out, drive.name, "result.json"))
    if not isinstance(row, dict) or "status" not in row:
        return None
    row.update({k: v for k, v in drive.axes().items() if k not in row})
    row.setdefault("metrics", {})
    return row

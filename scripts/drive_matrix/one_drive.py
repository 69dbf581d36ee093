"""Runs one drive in a folder of its own: simulate_urban and its SLAM runs (or, with --replay,
replay_backend on another matrix's dumps; steps.py), then evaluate_slam; writes the drive's
result.json, which a later run reads instead of running the drive again."""
import json
import os
import shutil
import time
import traceback

from .evaluation import baseline_label, dig, odometry_metrics, parse_metrics
from .files import last_log_line, read_json, sorted_listdir, unwritable, write_atomically
from .ground_truth import first_fix, write_full_ground_truth
from .own_metrics import absolute_offset_metrics, orientation_metrics, own_coverage, read_tum_stamps
from .steps import replay_backends, run_step, simulate_and_run_slam
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
    for name in ("sim", "slam_osm", "slam_no_osm", "slam_odom"):
        shutil.rmtree(os.path.join(d, name), ignore_errors=True)
    for name in ("evaluation.json", "evaluation_odom.json", "ground_truth_tum.txt", "result.json"):
        try:
            os.remove(os.path.join(d, name))
        except FileNotFoundError:
            pass
    for name in os.listdir(os.path.join(d, "logs")):
        try:
            os.remove(os.path.join(d, "logs", name))
        except OSError:
            pass


def _run_drive_steps(drive, ctx, d, logs, steps):
    _clean(d)
    write_atomically(os.path.join(d, "drive.json"), json.dumps(drive.axes(), indent=2) + "\n")
    notes = []
    if ctx.replay_from:
        sim, drive_dir = replay_backends(drive, ctx, d, logs, steps, notes)
    else:
        sim, drive_dir = simulate_and_run_slam(drive, ctx, d, logs, steps)
    return _evaluate_drive(drive, ctx, d, logs, steps, sim, drive_dir, notes)


def _evaluate_drive(drive, ctx, d, logs, steps, sim, drive_dir, notes):
    osm_out, no_osm_out = os.path.join(d, "slam_osm"), os.path.join(d, "slam_no_osm")
    gt = _whole_drive_ground_truth(d, sim, drive_dir, osm_out, notes)
    cmd = _evaluate_command(ctx, sim, drive_dir, osm_out, no_osm_out, gt, baseline_label(drive.gnss))
    report = os.path.join(osm_out, "timing.json")
    evaluation = _run_evaluate(ctx, d, logs, steps, cmd, _newer_evaluate_options(ctx, osm_out, report), notes)
    metrics = _drive_metrics(evaluation, sim, drive_dir, osm_out, no_osm_out, gt, report, drive.gnss == "origin")
    metrics.update(odometry_metrics(metrics, _evaluate_odometry(ctx, d, logs, steps, gt, notes), drive.gnss))
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


# Trajectory errors in the plane: the map's height is the first fix's altitude, which no run can
# correct (the OSM prior is 2-D, the fixes' altitude is off by default), and a canyon's first fix
# is tens of metres off vertically (poor VDOP, NLOS): in 3-D that constant buried every
# horizontal difference between the runs. Height is judged by height_drift and tilt.
PLANAR = ["--planar"]


def _evaluate_command(ctx, sim, drive_dir, osm_out, no_osm_out, gt, label):
    fix = first_fix(drive_dir)  # the map frame's origin (the plots' buildings are projected there)
    if fix is None:
        raise StepFailed("evaluate: no OXTS record with a GNSS fix in %s/oxts/data" % drive_dir)
    origin = "%.9f,%.9f" % (fix[0], fix[1])
    return [ctx.tool("evaluate_slam"), "--estimate", os.path.join(osm_out, "trajectory_tum.txt"),
            "--ground-truth", gt, "--origin", origin] + PLANAR + [
            "--baseline", os.path.join(no_osm_out, "trajectory_tum.txt"), "--baseline-label", label,
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
        run_step(ctx, steps, "evaluate", "evaluate", cmd + optional + ["--json"], eval_log,
                 stdout_path=evaluation_path)
    except StepFailed as e:
        if not optional:
            raise
        notes.append("evaluate_slam failed with %s (%s); evaluated without them" % (" ".join(optional), e))
        run_step(ctx, steps, "evaluate", "evaluate (without --run-report/--loops)", cmd + ["--json"],
                 eval_log, stdout_path=evaluation_path)
    evaluation = read_json(evaluation_path)
    if not isinstance(evaluation, dict):
        raise StepFailed("evaluate: evaluation.json is not JSON: %s" % (last_log_line(evaluation_path) or "empty"))
    return evaluation


def _evaluate_odometry(ctx, d, logs, steps, gt, notes):
    """evaluate_slam --json of the odometry + loops run (slam_odom) alone into
    evaluation_odom.json: its ATE by the same code, against the same ground truth and without
    alignment, as the other two runs'. None when the drive has no such folder (an 'origin'
    drive's run without OSM is that run; a replay of a matrix dumped before it). A failure is
    noted, not the drive's status: the other runs' numbers stand."""
    estimate = os.path.join(d, "slam_odom", "trajectory_tum.txt")
    if not os.path.isdir(os.path.dirname(estimate)):
        return None
    path = os.path.join(d, "evaluation_odom.json")
    try:
        run_step(ctx, steps, "evaluate_odom", "evaluate (odometry + loops)",
                 [ctx.tool("evaluate_slam"), "--estimate", estimate, "--ground-truth", gt] + PLANAR + ["--json"],
                 os.path.join(logs, "evaluate_slam_odom.log"), stdout_path=path)
    except StepFailed as e:
        notes.append("%s: no odometry + loops numbers" % e)
        return None
    return read_json(path)


def _drive_metrics(evaluation, sim, drive_dir, osm_out, no_osm_out, gt, report, first_fix_only):
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
    metrics.update(absolute_offset_metrics(sim, drive_dir, os.path.join(osm_out, "buildings_corrected.geojson"),
                                           first_fix_only))
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

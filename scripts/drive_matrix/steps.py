"""The tools one drive runs: simulate_urban and its SLAM runs (Drive.slam_runs()) through
offline_slam, or, with --replay, through replay_backend on another matrix's dumps. A tool that
prints its usage for a flag it does not know yet gives one status naming the flag."""
import os
import re
import shutil
import time

from .files import last_log_line, sorted_listdir
from .tools import StepFailed


def rejected_flags_hint(step, tool, flags, log_path):
    """The status of a tool that printed its usage (status 2) for an option it does not know:
    today's tools name it ("unknown option '--x'"), older builds list the options they know.
    None when the log has no usage (the tool failed for another reason)."""
    try:
        with open(log_path, errors="replace") as f:
            text = "".join(line for line in f if not line.startswith("$ "))  # not our command line
    except OSError:
        return None
    if "usage:" not in text:
        return None
    named = re.findall(r"unknown option '(--[\w-]+)'", text)
    if named:
        unknown = [f for f in flags if f in named]
    else:
        unknown = [f for f in flags if f.startswith("--") and f not in text]
    if unknown:
        return "%s: %s does not know %s (printed its usage; not built yet?)" % (step, tool, " ".join(unknown))
    return "%s: %s rejected its arguments (printed its usage; see logs/%s)" % (
        step, tool, os.path.basename(log_path))


def run_step(ctx, steps, key, step, cmd, log_path, new_flags=(), stdout_path=None):
    """ctx.run, its seconds in steps[key]; when it fails after printing its usage, the status
    names which of new_flags (the flags an older build may lack) it does not know."""
    t0 = time.monotonic()
    try:
        ctx.run(step, cmd, log_path, stdout_path)
    except StepFailed:
        hint = rejected_flags_hint(step, os.path.basename(cmd[0]), new_flags, log_path) if new_flags else None
        if hint:
            raise StepFailed(hint) from None
        raise
    finally:
        steps[key] = round(time.monotonic() - t0, 1)


def find_drive_dir(sim):
    """simulate_urban's KITTI raw drive folder (sim/<date>/<date>_drive_NNNN_sync), or None."""
    drives = sorted(p for p in (os.path.join(sim, a, b) for a in sorted_listdir(sim)
                                for b in sorted_listdir(os.path.join(sim, a)))
                    if re.search(r"_drive_\d+_sync$", p) and os.path.isdir(p))
    return drives[0] if drives else None


def simulate_and_run_slam(drive, ctx, d, logs, steps):
    """simulate_urban, then offline_slam for each of the drive's runs; returns (simulation
    folder, drive folder)."""
    sim = os.path.join(d, "sim")
    sim_log = os.path.join(logs, "simulate_urban.log")
    cmd = [ctx.tool("simulate_urban"), "--out", sim] + drive.sim_flags() + ctx.sim_args
    run_step(ctx, steps, "simulate", "simulate", cmd, sim_log, drive.new_flags())
    drive_dir = find_drive_dir(sim)
    if drive_dir is None:
        raise StepFailed("simulate: no drive folder in %s (%s)" % (sim, last_log_line(sim_log) or "empty log"))
    common = [ctx.tool("offline_slam"), "--kitti-raw", drive_dir, "--config", ctx.config]
    for run in drive.slam_runs():
        out = os.path.join(d, run.name)
        prior = ["--osm", os.path.join(sim, "prior.osm")] if run.with_osm else ["--no-osm"]
        # --dump: the back-end's inputs, for replay_backend (--replay)
        dump = ["--dump", os.path.join(out, "dump"), "--dump-without-clouds"] if ctx.dump else []
        run_step(ctx, steps, "offline_slam_" + run.suffix, "offline_slam " + run.title,
                 common + prior + list(run.flags) + ["--output", out] + dump,
                 os.path.join(logs, "offline_slam_%s.log" % run.suffix), run.flags)
    return sim, drive_dir


# The front-end's files of each run, copied from the replayed matrix (replay_backend writes only
# the back-end's).
REPLAY_COPIED = {"slam_osm": ("ground_truth_scans_tum.txt", "ground_truth_tum.txt", "loops.txt", "timing.json")}
REPLAY_COPIED_OTHERS = ("ground_truth_tum.txt", "timing.json")


def replay_backends(drive, ctx, d, logs, steps, notes):
    """--replay FROM: the same drive's back-end inputs (FROM/<drive>/slam_*/dump, written with
    --dump) through replay_backend with --set; the front-end's files (truth, loops, timing) and
    the simulation are taken from FROM unchanged. A matrix dumped before slam_odom existed has
    no dump of it: that run is left out (noted), the others are replayed."""
    src = os.path.join(ctx.replay_from, drive.name)
    sim = os.path.join(d, "sim")
    if not os.path.isdir(os.path.join(src, "sim")):
        raise StepFailed("replay: %s has no sim folder (run the matrix there first)" % src)
    os.symlink(os.path.join(os.path.abspath(src), "sim"), sim)
    drive_dir = find_drive_dir(sim)
    if drive_dir is None:
        raise StepFailed("replay: no drive folder in %s" % sim)
    sets = [a for kv in ctx.replay_sets for a in ("--set", kv)]
    for run in drive.slam_runs():
        dump = os.path.join(src, run.name, "dump")
        if not os.path.isfile(os.path.join(dump, "keyframes.csv")):
            if run.name == "slam_odom":
                notes.append("%s missing (dumped before the odometry + loops run existed): not replayed" % dump)
                continue
            raise StepFailed("replay: %s missing (run the matrix there with --dump)" % dump)
        out = os.path.join(d, run.name)
        extra = [] if run.with_osm else ["--no-osm"]
        run_step(ctx, steps, "replay_" + run.name, "replay_backend (%s)" % run.name,
                 [ctx.tool("replay_backend"), "--dump", dump, "--output", out, "--config", ctx.config]
                 + extra + list(run.flags) + sets, os.path.join(logs, "replay_%s.log" % run.name), run.flags)
        for name in REPLAY_COPIED.get(run.name, REPLAY_COPIED_OTHERS):
            if os.path.isfile(os.path.join(src, run.name, name)):
                shutil.copyfile(os.path.join(src, run.name, name), os.path.join(out, name))
    return sim, drive_dir

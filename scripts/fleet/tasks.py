"""The tasks a Dask worker runs: one drive (simulate_urban if simulated, then offline_slam with
its dump, clouds included) and the merge (merge_sessions over every dump). The tools run as in
the drive matrix (drive_matrix.tools: own process group, a log per tool, the log's last line in
the error); on a worker a tool also dies with the worker process (Context.die_with_parent).

A drive task may run more than once (Dask's retries after an error; the scheduler's reschedule
after its worker died), so it is idempotent: it removes what an earlier attempt left and writes
done.json atomically as its last act. A task that finds done.json returns it: the attempt before
finished, only its report was lost with its worker."""
import json
import os
import shutil
import time

from drive_matrix.files import read_json, write_atomically
from drive_matrix.steps import find_drive_dir, run_step
from drive_matrix.tools import Context, StepFailed

from .plan import drive_folder

# The flags simulate_urban gets for the fleet that an older build may not know yet (named in
# the error: "simulate_urban does not know --prior-seed (not built yet?)").
NEW_SIM_FLAGS = ("--world-seed", "--prior-seed", "--start-day")
MERGE_PARTIAL = 3  # merge_sessions: merged, but some sessions could not be read


class Settings:
    """What every task needs: the tools' folder, offline_slam's config, the output folder and
    the per-tool time limit. All paths absolute (a worker's working folder is its own)."""

    def __init__(self, bin_dir, config, out, step_timeout=None):
        self.bin_dir = os.path.abspath(bin_dir)
        self.config = os.path.abspath(config)
        self.out = os.path.abspath(out)
        self.step_timeout = step_timeout

    def context(self):
        return Context(self.bin_dir, self.config, self.out, [], step_timeout=self.step_timeout,
                       die_with_parent=True)


def run_drive(job, settings):
    """Runs one drive into OUT/drives/<name> and returns its done.json document; StepFailed (Dask
    retries the task) when a tool fails or leaves no dump."""
    folder = drive_folder(settings.out, job.name)
    done_path = os.path.join(folder, "done.json")
    done = read_json(done_path)
    if done is not None:
        return done
    logs = os.path.join(folder, "logs")
    os.makedirs(logs, exist_ok=True)
    attempt = record_attempt(folder)
    remove_earlier_outputs(folder)
    ctx, steps, t0 = settings.context(), {}, time.monotonic()
    kitti_dir, osm = job.kitti_dir, job.osm
    if job.simulated:
        kitti_dir, osm = simulate(ctx, job, folder, logs, steps)
    slam = os.path.join(folder, "slam")
    dump = os.path.join(slam, "dump")
    prior = ["--osm", osm] if osm else ["--no-osm"]
    run_step(ctx, steps, "offline_slam", "offline_slam",
             [ctx.tool("offline_slam"), "--kitti-raw", kitti_dir, "--config", settings.config] + prior
             + ["--output", slam, "--dump", dump], os.path.join(logs, "offline_slam.log"))
    if not os.path.isfile(os.path.join(dump, "keyframes.csv")):
        raise StepFailed("offline_slam: finished without a dump (%s has no keyframes.csv)" % dump)
    done = {"name": job.name, "job": job.describe(), "dump": dump, "attempt": attempt,
            "step_seconds": steps, "seconds": round(time.monotonic() - t0, 1)}
    write_atomically(done_path, json.dumps(done, indent=2) + "\n")
    return done


def simulate(ctx, job, folder, logs, steps):
    """simulate_urban into <folder>/sim; (the KITTI raw drive folder, its prior.osm)."""
    sim = os.path.join(folder, "sim")
    log = os.path.join(logs, "simulate_urban.log")
    run_step(ctx, steps, "simulate", "simulate", [ctx.tool("simulate_urban"), "--out", sim] + job.sim_flags,
             log, NEW_SIM_FLAGS)
    drive_dir = find_drive_dir(sim)
    if drive_dir is None:
        raise StepFailed("simulate: no drive folder in %s" % sim)
    return drive_dir, os.path.join(sim, "prior.osm")


def record_attempt(folder):
    """Appends this attempt to <folder>/attempts.log (never cleaned: the summary counts the
    tries) and returns its number."""
    path = os.path.join(folder, "attempts.log")
    with open(path, "a") as f:
        f.write("%s pid %d\n" % (time.strftime("%Y-%m-%d %H:%M:%S"), os.getpid()))
    return count_attempts(folder)


def count_attempts(folder):
    try:
        with open(os.path.join(folder, "attempts.log")) as f:
            return sum(1 for _ in f)
    except OSError:
        return 0


def remove_earlier_outputs(folder):
    """An earlier attempt's simulation and SLAM output, so that none of it is taken as this
    attempt's. The logs stay (each tool's log gets this attempt's command line appended)."""
    for name in ("sim", "slam"):
        shutil.rmtree(os.path.join(folder, name), ignore_errors=True)


def run_merge(dump_folders, settings, tile_size=None):
    """merge_sessions over the dumps into OUT/merged; {"exit": 0 or 3, "summary": its
    summary.json, "seconds": wall time}. StepFailed for any other exit or no summary."""
    merged = os.path.join(settings.out, "merged")
    shutil.rmtree(merged, ignore_errors=True)  # an earlier merge's map is not this one's
    os.makedirs(merged)
    logs = os.path.join(settings.out, "logs")
    os.makedirs(logs, exist_ok=True)
    ctx, t0 = settings.context(), time.monotonic()
    summary_path = os.path.join(merged, "summary.json")
    cmd = [ctx.tool("merge_sessions")]
    for d in dump_folders:
        cmd += ["--session", d]
    # The drives' parameters: a back-end replayed with other ones is another back-end.
    cmd += ["--output", merged, "--json", summary_path, "--config", settings.config]
    if tile_size is not None:
        cmd += ["--tile-size", str(tile_size)]
    code = ctx.run("merge", cmd, os.path.join(logs, "merge_sessions.log"), ok_codes=(0, MERGE_PARTIAL))
    summary = read_json(summary_path)
    if summary is None:
        raise StepFailed("merge: merge_sessions exited with status %d but wrote no readable %s"
                         % (code, summary_path))
    return {"exit": code, "summary": summary, "seconds": round(time.monotonic() - t0, 1)}

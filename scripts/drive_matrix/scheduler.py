"""Which drives run (a finished drive is read back, not run again), `jobs` at a time, longest
first so that the last one to finish is short; and the time estimate printed before.

The drives run on a thread pool (the default), or as tasks on a Dask cluster (executor "dask":
a LocalCluster of `jobs` worker processes, or the running cluster at `scheduler`), made by
fleet/cluster.py as for fleet_map.py; Dask is imported only then."""
import concurrent.futures
import copy
import threading
import time
import uuid

from .drives import SIM_SCANS_PER_S, SLAM_SCANS_PER_S
from .one_drive import drive_row, load_result, run_drive, world_problem
from .table import is_ok
from .tools import Stopped


def plan(drives, out, force=False, retry_failed=False):
    """(to_run, stored rows by drive): a drive with a result.json is not run again, unless force,
    or retry_failed and its status is not ok."""
    stored, to_run = {}, []
    for d in drives:
        row = None if force else load_result(d, out)
        if row is not None and retry_failed and not is_ok(row):
            row = None
        if row is None:
            to_run.append(d)
        else:
            stored[d] = row
    return to_run, stored


def print_flushed(text):
    print(text, flush=True)  # progress lines appear at once also when stdout is a file


EXECUTORS = ("threads", "dask")


def run_matrix(drives, ctx, to_run, jobs, runner=run_drive, log=print_flushed, executor="threads",
               scheduler=None):
    """Runs the drives of to_run (longest first, `jobs` at a time); returns {drive: row}. With
    executor "dask" or a scheduler address the drives are Dask tasks (run_on_dask)."""
    if not to_run:
        return {}
    order = sorted(to_run, key=lambda d: -d.estimated_seconds())
    if executor == "dask" or scheduler:
        return run_on_dask(order, ctx, jobs, runner, log, scheduler)
    return run_on_threads(order, ctx, jobs, runner, log)


def run_on_threads(order, ctx, jobs, runner, log):
    results = {}
    total, done = len(order), [0]
    lock = threading.Lock()

    def work(drive):
        if ctx.stopping.is_set():
            raise Stopped()
        problem = world_problem(drive)
        if not problem:
            with lock:
                log("[matrix] start %s" % drive.name)
        t0 = time.monotonic()
        row = runner(drive, ctx)
        with lock:
            done[0] += 1
            log("[matrix] %d/%d %s: %s (%.0f s)" % (done[0], total, drive.name, row["status"],
                                                    time.monotonic() - t0))
        return row

    pool = concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs))
    futures = {pool.submit(work, d): d for d in order}
    try:
        pending = set(futures)
        while pending:
            finished, pending = concurrent.futures.wait(pending, timeout=0.5)
            for f in finished:
                d = futures[f]
                try:
                    results[d] = f.result()
                except Stopped:
                    pass
                except Exception as e:  # the runner itself failed: still one line
                    results[d] = drive_row(d, "error: internal: %s: %s" % (type(e).__name__, e))
    except KeyboardInterrupt:
        ctx.stop_all()
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return results


def run_on_dask(order, ctx, jobs, runner, log, scheduler=None):
    """The drives as Dask tasks, one per drive: runner(drive, ctx) on a worker process, whose
    tools die with it (a worker killed mid-drive leaves no tool behind; the scheduler runs the
    drive again elsewhere). The runner must be importable on the workers (run_drive is: the
    cluster puts scripts/ on their path) or defined inside a function (sent by value)."""
    from distributed import as_completed  # only this executor needs Dask
    from fleet import cluster

    worker_ctx = copy.copy(ctx)  # the caller's context keeps running nothing itself
    worker_ctx.die_with_parent = True
    client, local = cluster.connect(scheduler, jobs)
    results, futures = {}, {}
    t0 = time.monotonic()
    try:
        for d in order:
            futures[client.submit(runner, d, worker_ctx, key="drive-%s-%s" % (d.name, uuid.uuid4().hex[:8]),
                                  pure=False)] = d
        for n, future in enumerate(as_completed(list(futures)), 1):
            d = futures[future]
            if future.status == "finished":
                row = future.result()
            else:  # the runner itself failed, or its worker died on every try: still one line
                e = future.exception()
                row = drive_row(d, "error: internal: %s: %s" % (type(e).__name__, e))
            results[d] = row
            log("[matrix] %d/%d %s: %s (at %.0f s)" % (n, len(order), d.name, row["status"],
                                                       time.monotonic() - t0))
    except KeyboardInterrupt:
        client.cancel(list(futures))  # a running drive of a cluster not ours runs to its end
        raise
    finally:
        cluster.close(client, local)
    return results


def estimate_text(drives, jobs):
    secs = sum(d.estimated_seconds() for d in drives)
    longest = max((d.estimated_seconds() for d in drives), default=0)
    return ("%d drives, %.0f scans; estimated %.0f min on 2 cores, --jobs %d (%.0f scans/s "
            "simulate_urban, %.0f scans/s offline_slam; longest drive %.0f min)" % (
                len(drives), sum(d.estimated_scans() for d in drives), secs / 60, jobs,
                SIM_SCANS_PER_S, SLAM_SCANS_PER_S, longest / 60))

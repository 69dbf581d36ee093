"""Which drives run (a finished drive is read back, not run again), `jobs` at a time, longest
first so that the last one to finish is short; and the time estimate printed before."""
import concurrent.futures
import threading
import time

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


def run_matrix(drives, ctx, to_run, jobs, runner=run_drive, log=print_flushed):
    """Runs the drives of to_run (longest first, `jobs` at a time); returns {drive: row}."""
    results = {}
    if not to_run:
        return results
    order = sorted(to_run, key=lambda d: -d.estimated_seconds())
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


def estimate_text(drives, jobs):
    secs = sum(d.estimated_seconds() for d in drives)
    longest = max((d.estimated_seconds() for d in drives), default=0)
    return ("%d drives, %.0f scans; estimated %.0f min on 2 cores, --jobs %d (%.0f scans/s "
            "simulate_urban, %.0f scans/s offline_slam; longest drive %.0f min)" % (
                len(drives), sum(d.estimated_scans() for d in drives), secs / 60, jobs,
                SIM_SCANS_PER_S, SLAM_SCANS_PER_S, longest / 60))

"""One fleet run on a Dask client: every drive as a task (retried), then the merge of every dump
made (and given) as one more task; returns the sessions' rows and the merge's result."""
import os
import time
import uuid

from distributed import as_completed

from . import tasks
from .plan import drive_folder
from .report import Progress

DRIVE_RETRIES = 2  # a drive is tried at most three times (a worker's death is rescheduled besides)
POLL_SECONDS = 1.0  # how often the progress line's clock is redrawn while nothing finishes


def task_key(kind, name):
    """A readable, unique task key (a retry keeps its key; a new run gets new ones)."""
    return "%s-%s-%s" % (kind, name, uuid.uuid4().hex[:8])


def submit_drives(client, jobs, settings):
    """{future: job}, one task per drive."""
    return {client.submit(tasks.run_drive, job, settings, key=task_key("drive", job.name),
                          retries=DRIVE_RETRIES, pure=False): job for job in jobs}


def drive_row(result, status):
    return {"name": result["name"], "status": status, "dump": result["dump"],
            "attempts": result.get("attempt"), "seconds": result.get("seconds"),
            "step_seconds": result.get("step_seconds") or {}}


def failed_row(job, settings, error):
    return {"name": job.name, "status": "failed", "dump": None, "error": error,
            "attempts": tasks.count_attempts(drive_folder(settings.out, job.name))}


def error_text(exc):
    """A task's error in one line: a tool's StepFailed says it all; anything else (KilledWorker:
    its worker died on every try) gets its type."""
    if type(exc).__name__ == "StepFailed":
        return str(exc)
    return "%s: %s" % (type(exc).__name__, exc)


def collect_drives(futures, settings, progress):
    """{name: row} as the tasks finish, the progress line kept current."""
    rows = {}
    done = as_completed(list(futures))
    while not done.is_empty():
        batch = done.next_batch(block=False)
        if not batch:
            progress.show()
            time.sleep(POLL_SECONDS)
            continue
        for future in batch:
            job = futures[future]
            if future.status == "finished":
                rows[job.name] = drive_row(future.result(), "ok")
            else:
                rows[job.name] = failed_row(job, settings, error_text(future.exception()))
            future.release()
            progress.finished_one(rows[job.name]["status"] == "ok")
    progress.end()
    return rows


def run_merge(client, dump_folders, settings, tile_size=None):
    """tasks.run_merge's result, or {"error": ...} when no map was made."""
    if not dump_folders:
        return {"error": "no session to merge (every drive failed and no --dumps given)"}
    future = client.submit(tasks.run_merge, dump_folders, settings, tile_size,
                           key=task_key("merge", "sessions"), pure=False)
    try:
        return future.result()
    except Exception as e:  # merge_sessions failed (StepFailed), or its worker died three times
        return {"error": error_text(e)}


def run_fleet(client, jobs, to_run, finished, dumps, settings, tile_size=None, stream=None, log=print):
    """(session rows in the order given: drives, then dumps; the merge's result)."""
    futures = submit_drives(client, to_run, settings)
    log("[fleet] %d drives (%d finished before), %d dumps given; %d workers -> %s" % (
        len(jobs), len(finished), len(dumps), len(client.scheduler_info().get("workers", {})), settings.out))
    rows = collect_drives(futures, settings, Progress(len(to_run), stream)) if futures else {}
    rows.update({name: drive_row(result, "finished before") for name, result in finished.items()})
    sessions = [rows[job.name] for job in jobs]
    sessions += [{"name": d.name, "status": "dump given", "dump": d.folder} for d in dumps]
    dump_folders = [r["dump"] for r in sessions if r.get("dump")]
    log("[fleet] merging %d sessions (merge_sessions; log in %s)" % (
        len(dump_folders), os.path.join(settings.out, "logs", "merge_sessions.log")))
    return sessions, run_merge(client, dump_folders, settings, tile_size)

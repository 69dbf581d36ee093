"""Which sessions go into the map: drives to run (simulated ones through one world, or KITTI
raw folders on disk) and dumps made before, taken as they are (the incremental case). A drive
whose done.json (tasks.py) records the same job is finished: it is read back, not run again."""
import os
import re

from drive_matrix.files import read_json, sorted_listdir

DRIVE_FOLDER = re.compile(r"_drive_\d+_sync$")


class FleetError(Exception):
    """Bad input (exit status 2): the message says which option and why."""


class DriveJob:
    """One drive to run: a simulated drive (sim_flags for simulate_urban) or a KITTI raw folder
    (kitti_dir, with the OSM prior osm, or None for offline_slam --no-osm)."""

    def __init__(self, name, sim_flags=None, kitti_dir=None, osm=None):
        self.name = name
        self.sim_flags = list(sim_flags) if sim_flags is not None else None
        self.kitti_dir = kitti_dir
        self.osm = osm

    @property
    def simulated(self):
        return self.sim_flags is not None

    def describe(self):
        """The job as JSON (done.json keeps it: a changed job is run again)."""
        if self.simulated:
            return {"name": self.name, "simulate_urban": self.sim_flags}
        return {"name": self.name, "kitti_raw": self.kitti_dir, "osm": self.osm}

    def __repr__(self):
        return "DriveJob(%s)" % self.name


class Dumps:
    """A dump given with --dumps: merged as it is."""

    def __init__(self, name, folder):
        self.name = name
        self.folder = folder


def simulated_jobs(count, world_seed, prior_seed, length=None, sim_args=(), first_seed=1):
    """`count` drives through one world (--world-seed) with one prior map (--prior-seed): each
    its own route seed and its own day (--start-day), as a fleet's drives on different days."""
    jobs = []
    for i in range(count):
        seed = first_seed + i
        flags = ["--seed", str(seed), "--world-seed", str(world_seed), "--prior-seed", str(prior_seed),
                 "--start-day", str(i)]
        if length is not None:
            flags += ["--length", str(length)]
        jobs.append(DriveJob("sim_w%d_s%d" % (world_seed, seed), sim_flags=flags + list(sim_args)))
    return jobs


def find_kitti_drives(folder):
    """The KITTI raw drive folders in `folder`: itself when it holds velodyne_points, else its
    *_drive_NNNN_sync folders one or two levels down (a date folder, simulate_urban's --out)."""
    if os.path.isdir(os.path.join(folder, "velodyne_points")):
        return [folder]
    found = []
    for a in sorted_listdir(folder):
        first = os.path.join(folder, a)
        if DRIVE_FOLDER.search(a) and os.path.isdir(first):
            found.append(first)
            continue
        found += [os.path.join(first, b) for b in sorted_listdir(first)
                  if DRIVE_FOLDER.search(b) and os.path.isdir(os.path.join(first, b))]
    return found


def simulator_prior(drive_dir):
    """The prior.osm simulate_urban wrote beside a drive (SIM/<date>/<drive>), or None."""
    path = os.path.join(os.path.dirname(os.path.dirname(drive_dir)), "prior.osm")
    return path if os.path.isfile(path) else None


def kitti_jobs(folders, osm=None):
    """One job per drive found in the folders; the prior: osm, else simulate_urban's prior.osm
    beside the drive, else none (--no-osm)."""
    jobs = []
    for folder in folders:
        drives = find_kitti_drives(os.path.abspath(folder))
        if not drives:
            raise FleetError("--drives-from %s: no KITTI raw drive (velodyne_points, or "
                             "*_drive_NNNN_sync folders) in it" % folder)
        for d in drives:
            jobs.append(DriveJob(os.path.basename(d), kitti_dir=d, osm=osm or simulator_prior(d)))
    return jobs


def dump_name(folder):
    """A dump's name in the summary: its folder's, or the run's when it is <run>/slam/dump or
    <run>/dump (offline_slam --dump's usual place)."""
    parts = os.path.normpath(os.path.abspath(folder)).split(os.sep)
    while len(parts) > 1 and parts[-1] in ("dump", "slam"):
        parts.pop()
    return parts[-1] or "dump"


def given_dumps(folders):
    """--dumps: each must be a folder (its contents are merge_sessions' to judge)."""
    dumps = []
    for folder in folders:
        if not os.path.isdir(folder):
            raise FleetError("--dumps %s: not a folder" % folder)
        dumps.append(Dumps(dump_name(folder), os.path.abspath(folder)))
    return dumps


def make_names_unique(sessions):
    """Two sessions of one name (drive_0001 of two days) become name, name.2, ...: each drive
    has a folder of its own and one line in the summary."""
    seen = {}
    for s in sessions:
        n = seen.get(s.name, 0) + 1
        seen[s.name] = n
        if n > 1:
            s.name = "%s.%d" % (s.name, n)
    return sessions


def drive_folder(out, name):
    return os.path.join(out, "drives", name)


def split_finished(jobs, out, force=False):
    """(jobs to run, {name: stored result}): a job is finished when its done.json records the same
    job; force runs every job again. For a job to run, a stale done.json is removed, so that a
    task of this run never takes it for its own (tasks.run_drive returns a done.json it finds),
    and so is the count of an earlier run's attempts."""
    to_run, finished = [], {}
    for job in jobs:
        folder = drive_folder(out, job.name)
        stored = read_json(os.path.join(folder, "done.json"))
        if stored is not None and not force and stored.get("job") == job.describe():
            finished[job.name] = stored
            continue
        for name in ("done.json", "attempts.log"):
            if os.path.exists(os.path.join(folder, name)):
                os.remove(os.path.join(folder, name))
        to_run.append(job)
    return to_run, finished

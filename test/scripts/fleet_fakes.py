"""The fakes fleet_map_test.py runs with: simulate_urban, offline_slam and merge_sessions as one
small Python program in a temporary bin folder (as matrix_fakes.py does for the drive matrix).
Not a test file itself.

Behaviour by environment, each naming one drive (the folder name under OUT/drives):
  FAKE_KILL_WORKER  offline_slam kills the Dask worker process running it (its parent) on the
                    drive's first attempt only, then waits to be killed with it
  FAKE_FAIL         offline_slam fails on every attempt (status 1, a clear last line)
  FAKE_CORRUPT      offline_slam writes a dump whose keyframes.csv is not numbers
FAKE_CALLS: a file each call is appended to (one JSON list a line); FAKE_STATE: a folder where
offline_slam counts each drive's attempts. merge_sessions reads every --session's keyframes.csv,
leaves out (exit 3, listed as not ok) a session whose file is not numbers, and fails (exit 1) when
none can be read."""
import json
import os
import stat

FAKE_ENV = ("FAKE_CALLS", "FAKE_STATE", "FAKE_KILL_WORKER", "FAKE_FAIL", "FAKE_CORRUPT")

FAKE_TOOL = r'''#!/usr/bin/python3
import json, os, signal, sys, time
name = os.path.basename(sys.argv[0])
args = sys.argv[1:]
with open(os.environ["FAKE_CALLS"], "a") as f:
    f.write(json.dumps([name] + args) + "\n")
def opt(key):
    return args[args.index(key) + 1]
def count_attempt(drive):
    path = os.path.join(os.environ["FAKE_STATE"], drive + ".attempts")
    with open(path, "a") as f:
        f.write("x\n")
    return sum(1 for _ in open(path))
def kill_parent_worker():
    # Only a Dask worker process (a multiprocessing child) is killed, never a test runner.
    parent = os.getppid()
    cmdline = open("/proc/%d/cmdline" % parent, "rb").read().decode(errors="replace")
    if "multiprocessing" not in cmdline:
        sys.stderr.write("fake offline_slam: parent %d is not a Dask worker: %s\n" % (parent, cmdline))
        sys.exit(97)
    os.kill(parent, signal.SIGKILL)
    time.sleep(20)  # setpriv's death signal ends this at once; without it: give up later
    sys.exit(98)
if name == "simulate_urban":
    out = opt("--out")
    seed, day = int(opt("--seed")), int(opt("--start-day"))
    date = "2020_01_%02d" % (day + 1)
    drive = os.path.join(out, date, "%s_drive_%04d_sync" % (date, seed))
    os.makedirs(os.path.join(drive, "velodyne_points", "data"))
    open(os.path.join(out, "prior.osm"), "w").write("<osm/>\n")
    print("scans: 10")
elif name == "offline_slam":
    out, dump = opt("--output"), opt("--dump")
    drive = os.path.basename(os.path.dirname(out))
    attempt = count_attempt(drive)
    if drive == os.environ.get("FAKE_KILL_WORKER") and attempt == 1:
        kill_parent_worker()
    if drive == os.environ.get("FAKE_FAIL"):
        sys.stderr.write("offline_slam: cannot read scan 7 of the drive: truncated file\n")
        sys.exit(1)
    os.makedirs(dump)
    with open(os.path.join(dump, "keyframes.csv"), "w") as f:
        f.write("garbage\x00\x01\n" if drive == os.environ.get("FAKE_CORRUPT") else "0 0.0 0.0\n1 1.5 0.0\n")
    print("done")
elif name == "merge_sessions":
    sessions = [args[i + 1] for i, a in enumerate(args) if a == "--session"]
    rows, keyframes = [], 0
    for s in sessions:
        try:
            lines = open(os.path.join(s, "keyframes.csv"), errors="replace").read().splitlines()
            for n, line in enumerate(lines, 1):
                for word in line.split():
                    try:
                        float(word)
                    except ValueError:
                        raise ValueError("keyframes.csv line %d: %r is not a number" % (n, word[:20]))
            rows.append({"dir": s, "ok": True})
            keyframes += len(lines)
        except (OSError, ValueError) as e:
            rows.append({"dir": s, "ok": False, "error": str(e)})
    good = sum(1 for r in rows if r["ok"])
    if not good:
        sys.stderr.write("merge_sessions: no session could be read\n")
        sys.exit(1)
    os.makedirs(opt("--output"), exist_ok=True)
    json.dump({"sessions": rows, "keyframes": keyframes, "inter_session_loops": good - 1,
               "buildings_by_drives": {"1": 5, str(good): 2}, "merge_seconds": 0.25},
              open(opt("--json"), "w"))
    sys.exit(0 if good == len(rows) else 3)
'''


def make_fake_bin(folder):
    os.makedirs(folder, exist_ok=True)
    for tool in ("simulate_urban", "offline_slam", "merge_sessions"):
        path = os.path.join(folder, tool)
        with open(path, "w") as f:
            f.write(FAKE_TOOL)
        os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)


def read_calls(path):
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return [json.loads(line) for line in f]

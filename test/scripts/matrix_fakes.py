"""The fakes the drive matrix's tests run with: the entry point scripts/slam_matrix.py loaded
by path, fake simulate_urban / offline_slam / replay_backend / evaluate_slam programs (one small
Python script in a temporary bin folder) and a test case's fixture around them. Not a test file
itself: slam_matrix_test.py and slam_matrix_gnss_test.py import it."""
import contextlib
import importlib.util
import io
import json
import os
import shutil
import stat
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
SCRIPT = os.path.join(REPO, "scripts", "slam_matrix.py")
PACKAGE = os.path.join(REPO, "scripts", "drive_matrix")

# The entry point, loaded by path as a tool would; it puts scripts/ on the module path, so the
# package's modules import below.
spec = importlib.util.spec_from_file_location("slam_matrix", SCRIPT)
sm = importlib.util.module_from_spec(spec)
spec.loader.exec_module(sm)

from drive_matrix.grid import axes_from_args, build_grid  # noqa: E402
from drive_matrix.tools import TOOLS  # noqa: E402

FAKE_SWITCHES = ("FAKE_OLD_SIM", "FAKE_NEW_EVAL", "FAKE_NO_GNSS_OPTION")

# One program for the four tools, dispatching on its name. FAKE_CALLS: a file each call is
# appended to. Behaviour by environment: FAKE_OLD_SIM (simulate_urban prints its usage for the new
# flags; "names_it": names the first, as the tools do today), FAKE_NEW_EVAL (evaluate_slam knows
# --run-report/--loops and writes coverage/loops keys), FAKE_NO_GNSS_OPTION (offline_slam and
# replay_backend do not know --gnss: an older build);
# by seed: 13 -> simulate_urban fails, 66 -> offline_slam --no-osm crashes.
# evaluate_slam: ATE 0.12 m of the estimate (0.3 m when it is slam_odom's), 0.2 m of the baseline.
FAKE_TOOL = r'''#!/usr/bin/python3
import json, os, signal, sys
name = os.path.basename(sys.argv[0])
args = sys.argv[1:]
with open(os.environ["FAKE_CALLS"], "a") as f:
    f.write(json.dumps([name] + args) + "\n")
def opt(key, default=None):
    return args[args.index(key) + 1] if key in args else default
NEW = ("--prior-model", "--rtk", "--manoeuvres", "--drop-scans", "--dropout-burst")
if name in ("offline_slam", "replay_backend") and os.environ.get("FAKE_NO_GNSS_OPTION") and "--gnss" in args:
    sys.stderr.write("%s: unknown option '--gnss'\nusage: %s [options]\n" % (name, name))
    sys.exit(2)
if name == "simulate_urban":
    if os.environ.get("FAKE_OLD_SIM") and any(a in NEW for a in args):
        if os.environ["FAKE_OLD_SIM"] == "names_it":  # the tools' CommandLine message
            sys.stderr.write("simulate_urban: unknown option '%s'\nusage: simulate_urban --out DIR "
                             "[options]\nRun 'simulate_urban --help' for the options.\n"
                             % [a for a in args if a in NEW][0])
        else:
            sys.stderr.write("usage: simulate_urban --out DIR [options]\n  --osm FILE\n  --sensor hdl64e|os1_64\n")
        sys.exit(2)
    seed = int(opt("--seed", "1"))
    if seed == 13:
        sys.stderr.write("[####      ] 10/40\rsimulate_urban: cannot write scan 10: disk full\n")
        sys.exit(1)
    out = opt("--out")
    drive = os.path.join(out, "2020_01_01", "2020_01_01_drive_0001_sync")
    os.makedirs(os.path.join(drive, "velodyne_points", "data"))
    os.makedirs(os.path.join(drive, "oxts", "data"))
    os.makedirs(os.path.join(out, "ground_truth"))
    n = 20
    with open(os.path.join(drive, "velodyne_points", "data", "0000000000.bin"), "wb") as f:
        f.write(b"\0" * 1000)
    with open(os.path.join(drive, "oxts", "timestamps.txt"), "w") as f:
        for i in range(n):
            f.write("2020-01-01 12:00:%02d.%09d\n" % (i // 10, (i % 10) * 100000000))
    with open(os.path.join(drive, "oxts", "data", "0000000000.txt"), "w") as f:
        f.write("49.0 8.4 110.0 0 0 0\n")
    with open(os.path.join(out, "ground_truth", "poses_imu.txt"), "w") as f:
        for i in range(n):
            f.write("1 0 0 %g 0 1 0 0 0 0 1 0\n" % (0.8 * i))
    json.dump({"seed": seed, "enu_origin": {"lat": 49.0, "lon": 8.4, "alt": 110.0}, "scans": n,
               "route_length_m": 15.2, "revisits": 3}, open(os.path.join(out, "sim_info.json"), "w"))
    for f in ("prior.osm", "buildings_true.geojson"):
        open(os.path.join(out, f), "w").write("x\n")
    print("scans: %d" % n)
elif name == "offline_slam":
    out = opt("--output")
    sim_info = os.path.join(os.path.dirname(os.path.dirname(opt("--kitti-raw"))), "sim_info.json")
    seed = json.load(open(sim_info))["seed"]
    if seed == 66 and "--no-osm" in args:
        sys.stderr.write("offline_slam: optimising\n")
        sys.stderr.flush()
        os.kill(os.getpid(), signal.SIGSEGV)
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "trajectory_tum.txt"), "w") as f:
        for i in range(2, 18):  # 0.2 .. 1.7 s of the 0 .. 1.9 s drive
            f.write("%d.%09d %g 0 0 0 0 0 1\n" % (1577880000 + i // 10, (i % 10) * 100000000, 0.8 * i))
    open(os.path.join(out, "ground_truth_tum.txt"), "w").write("")
    json.dump({"scans": 20, "keyframes": 16, "loops": 4, "scans_per_second": 25.5,
               "tracking": {"scans": 20, "matched": 20, "failed_matches": 0, "lost_events": 0,
                            "longest_no_keyframe_s": 0.1}}, open(os.path.join(out, "timing.json"), "w"))
    open(os.path.join(out, "loops.csv"), "w").write("a,b\n")
    if "--dump" in args:
        os.makedirs(opt("--dump"))
        open(os.path.join(opt("--dump"), "keyframes.csv"), "w").write("0 0 0\n")
    print("done")
elif name == "replay_backend":
    out = opt("--output")
    os.makedirs(out)
    with open(os.path.join(out, "trajectory_tum.txt"), "w") as f:
        for i in range(2, 18):
            f.write("%d.%09d %g 0 0 0 0 0 1\n" % (1577880000 + i // 10, (i % 10) * 100000000, 0.8 * i))
elif name == "evaluate_slam":
    new = bool(os.environ.get("FAKE_NEW_EVAL"))
    if new and "--run-report" in args and os.environ["FAKE_NEW_EVAL"] == "broken":
        sys.stderr.write("evaluate_slam: --run-report 'x' has no \"tracking\" section\n")
        sys.exit(1)
    if "--help" in args:
        sys.stderr.write("evaluate_slam: unexpected argument '--help'\nusage: evaluate_slam --estimate FILE "
                         "--ground-truth FILE%s [--json]\n" % (" [--run-report FILE] [--loops FILE]" if new else ""))
        sys.exit(2)
    odom = "/slam_odom/" in opt("--estimate")
    doc = {"slam": {"ate_m": {"mean": 0.3 if odom else 0.12}, "rpe_trans_m": {"mean": 0.007 if odom else 0.006}}}
    if "--baseline" in args:
        label = opt("--baseline-label", "baseline")
        doc[label] = {"ate_m": {"mean": 0.2}, "rpe_trans_m": {"mean": 0.005}}
        doc["ate_change_vs_" + label] = -0.4
    if "--buildings-true" in args:
        doc["buildings_prior"] = {"mean_corner_error_m": 1.4, "overlapping_pairs": 10, "matched": 28}
        doc["buildings_corrected"] = {"mean_corner_error_m": 0.4, "overlapping_pairs": 0, "matched": 28}
    if new:
        doc["coverage"] = {"fraction": 0.97, "longest_gap_s": 0.3}
        doc["loops"] = {"revisits": 5, "revisits_closed": 4, "recall": 0.8, "accepted": 6, "false": 1}
    print(json.dumps(doc))
'''


def make_fake_bin(folder):
    os.makedirs(folder, exist_ok=True)
    for tool in TOOLS + ("replay_backend",):
        path = os.path.join(folder, tool)
        with open(path, "w") as f:
            f.write(FAKE_TOOL)
        os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)


def run_main(argv):
    """(exit status, printed text) of slam_matrix.main."""
    lines = []
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        status = sm.main(argv, log=lines.append)
    return status, "\n".join(lines) + err.getvalue()


def preset_drives(name, extra=()):
    args = sm.build_parser().parse_args(["--preset", name] + list(extra))
    return build_grid(*axes_from_args(args))



class FakeTools:
    """A test case's fixture (mixed into a unittest.TestCase): the fake tools in a temporary bin
    folder, the output folder, the file of their calls and the environment the fakes read."""


    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="slam_matrix_test_")
        self.bin = os.path.join(self.tmp, "bin")
        make_fake_bin(self.bin)
        self.out = os.path.join(self.tmp, "out")
        self.calls = os.path.join(self.tmp, "calls.jsonl")
        self.config = os.path.join(self.tmp, "sim.yaml")
        open(self.config, "w").write("{}\n")
        self.env = {k: os.environ.get(k) for k in ("FAKE_CALLS",) + FAKE_SWITCHES}
        os.environ["FAKE_CALLS"] = self.calls
        for k in FAKE_SWITCHES:
            os.environ.pop(k, None)

    def tearDown(self):
        for k, v in self.env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        shutil.rmtree(self.tmp, ignore_errors=True)

    def matrix(self, *argv):
        return run_main(["--bin", self.bin, "--out", self.out, "--config", self.config] + list(argv))

    def tool_calls(self):
        if not os.path.exists(self.calls):
            return []
        return [json.loads(line) for line in open(self.calls)]


    def result(self, drive_name):
        with open(os.path.join(self.out, drive_name, "result.json")) as f:
            return json.load(f)

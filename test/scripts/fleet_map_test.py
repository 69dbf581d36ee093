"""Tests of scripts/fleet_map.py (package scripts/fleet) and the drive matrix's Dask executor,
on local Dask clusters of worker processes with fake C++ tools (fleet_fakes.py, matrix_fakes.py):
every drive exactly once in the map although a worker process is killed mid-drive, a drive that
fails on every try, a corrupt dump, resume, and the matrix's rows on Dask against the thread
pool's. About 20 s (each test starts a cluster of two worker processes).

    /usr/bin/python3 -m unittest test/scripts/fleet_map_test.py -v      (from the repo root)
"""
import contextlib
import io
import json
import os
import re
import shutil
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:  # run by path (python3 -m unittest test/scripts/fleet_map_test.py)
    sys.path.insert(0, HERE)

# matrix_fakes loads scripts/slam_matrix.py, which puts scripts/ on the module path.
from matrix_fakes import FakeTools as MatrixFakeTools  # noqa: E402
from matrix_fakes import REPO  # noqa: E402
from fleet_fakes import FAKE_ENV, make_fake_bin, read_calls  # noqa: E402

try:
    from fleet import cluster
    from fleet.cli import main as fleet_main
    HAVE_DASK = True
except ImportError:  # python3-distributed not installed (scripts/setup.sh installs it)
    HAVE_DASK = False

from drive_matrix.drives import Drive, World  # noqa: E402
from drive_matrix.one_drive import drive_row  # noqa: E402
from drive_matrix.scheduler import run_matrix  # noqa: E402
from drive_matrix.tools import Context  # noqa: E402

SCRIPTS = os.path.join(REPO, "scripts")
def write_file(path, text):
    with open(path, "w") as f:
        f.write(text)


NEEDS_DASK = unittest.skipUnless(HAVE_DASK, "python3-distributed missing (scripts/setup.sh installs it)")


@NEEDS_DASK
class FleetMapTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="fleet_map_test_")
        self.bin = os.path.join(self.tmp, "bin")
        make_fake_bin(self.bin)
        self.out = os.path.join(self.tmp, "out")
        self.config = os.path.join(self.tmp, "sim.yaml")
        write_file(self.config, "{}\n")
        self.calls = os.path.join(self.tmp, "calls.jsonl")
        state = os.path.join(self.tmp, "state")
        os.makedirs(state)
        self.saved_env = {k: os.environ.get(k) for k in FAKE_ENV}
        for k in FAKE_ENV:
            os.environ.pop(k, None)
        # Set before each run's cluster starts: its worker processes inherit the environment.
        os.environ.update(FAKE_CALLS=self.calls, FAKE_STATE=state)

    def tearDown(self):
        for k, v in self.saved_env.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        shutil.rmtree(self.tmp, ignore_errors=True)

    def fleet(self, *argv):
        """(exit status, printed text, fleet_summary.json or None)."""
        lines, err = [], io.StringIO()
        with contextlib.redirect_stderr(err):
            status = fleet_main(["--bin", self.bin, "--config", self.config, "--out", self.out, "--workers", "2"]
                                + list(argv), log=lines.append, stream=io.StringIO())
        path = os.path.join(self.out, "fleet_summary.json")
        doc = None
        if os.path.exists(path):
            with open(path) as f:
                doc = json.load(f)
        return status, "\n".join(lines) + err.getvalue(), doc

    def simulate(self, n, *argv):
        return self.fleet("--simulate", str(n), "--world-seed", "4", "--prior-seed", "9", "--sim-args", "",
                          *argv)

    def tool_calls(self, tool):
        return [c[1:] for c in read_calls(self.calls) if c[0] == tool]

    def merged_sessions(self):
        [merge] = self.tool_calls("merge_sessions")
        return [merge[i + 1] for i, a in enumerate(merge) if a == "--session"]

    def offline_slam_drives(self):
        return [os.path.basename(os.path.dirname(c[c.index("--output") + 1])) for c in self.tool_calls("offline_slam")]

    def test_a_killed_worker_s_drive_runs_again_and_is_merged_once(self):
        os.environ["FAKE_KILL_WORKER"] = "sim_w4_s2"
        status, text, doc = self.simulate(3)
        self.assertEqual(status, 0, text)
        names = ["sim_w4_s1", "sim_w4_s2", "sim_w4_s3"]
        self.assertEqual([s["name"] for s in doc["sessions"]], names)
        self.assertEqual([s["status"] for s in doc["sessions"]], ["ok"] * 3)
        self.assertEqual([s["attempts"] for s in doc["sessions"]], [1, 2, 1], text)
        self.assertEqual(sorted(self.offline_slam_drives()), ["sim_w4_s1", "sim_w4_s2", "sim_w4_s2", "sim_w4_s3"])
        dumps = [os.path.join(self.out, "drives", n, "slam", "dump") for n in names]
        self.assertEqual(sorted(self.merged_sessions()), dumps)  # each drive exactly once
        self.assertEqual(doc["map"]["keyframes"], 6)
        self.assertTrue(doc["map"]["complete"])
        self.assertEqual(doc["counts"]["sessions_in_map"], 3)
        # The simulated drives: one world, one prior, a seed and a day each.
        sims = self.tool_calls("simulate_urban")
        self.assertEqual(sorted((c[c.index("--seed") + 1], c[c.index("--start-day") + 1]) for c in sims),
                         [("1", "0"), ("2", "1"), ("2", "1"), ("3", "2")])
        self.assertTrue(all(c[c.index("--world-seed") + 1] == "4" and c[c.index("--prior-seed") + 1] == "9"
                            for c in sims))
        slam = self.tool_calls("offline_slam")[0]
        self.assertNotIn("--dump-without-clouds", slam)
        self.assertTrue(slam[slam.index("--osm") + 1].endswith("/sim/prior.osm"))

    def test_a_drive_failing_every_time_is_reported_and_the_map_made_from_the_rest(self):
        os.environ["FAKE_FAIL"] = "sim_w4_s1"
        status, text, doc = self.simulate(2, "--tile-size", "250")
        self.assertEqual(status, 0, text)
        failed = doc["sessions"][0]
        self.assertEqual((failed["status"], failed["attempts"], failed["in_map"]), ("failed", 3, False))
        self.assertIn("cannot read scan 7 of the drive: truncated file", failed["error"])
        self.assertIn("FAILED sim_w4_s1 after 3 tries: offline_slam: offline_slam exited with status 1", text)
        self.assertEqual(self.offline_slam_drives().count("sim_w4_s1"), 3)
        self.assertEqual(self.merged_sessions(), [os.path.join(self.out, "drives", "sim_w4_s2", "slam", "dump")])
        merge = self.tool_calls("merge_sessions")[0]
        self.assertEqual(merge[merge.index("--tile-size") + 1], "250")
        self.assertEqual(doc["counts"], {"drives": 2, "ok": 1, "failed": 1, "dumps_given": 0, "sessions_in_map": 1})

    def test_a_corrupt_dump_is_left_out_with_one_error_and_given_dumps_are_not_run(self):
        kitti = os.path.join(self.tmp, "kitti", "2011_09_26")
        for n in (1, 2):
            os.makedirs(os.path.join(kitti, "2011_09_26_drive_%04d_sync" % n, "velodyne_points"))
        old = os.path.join(self.tmp, "old_run", "slam", "dump")
        os.makedirs(old)
        write_file(os.path.join(old, "keyframes.csv"), "0 2 3\n")
        os.environ["FAKE_CORRUPT"] = "2011_09_26_drive_0002_sync"
        status, text, doc = self.fleet("--drives-from", os.path.dirname(kitti), "--dumps", old)
        self.assertEqual(status, 0, text)
        self.assertEqual([(s["name"], s["status"], s["in_map"]) for s in doc["sessions"]],
                         [("2011_09_26_drive_0001_sync", "ok", True), ("2011_09_26_drive_0002_sync", "ok", False),
                          ("old_run", "dump given", True)])
        self.assertEqual(doc["sessions"][1]["error"], "merge: keyframes.csv line 1: 'garbage\\x00\\x01' is not a number")
        self.assertEqual(text.count("NOT IN MAP"), 1, text)
        self.assertIn("NOT IN MAP 2011_09_26_drive_0002_sync", text)
        self.assertEqual((doc["map"]["exit"], doc["map"]["complete"], doc["map"]["keyframes"]), (3, False, 3))
        self.assertEqual(len(self.merged_sessions()), 3)
        self.assertEqual(sorted(self.offline_slam_drives()), ["2011_09_26_drive_0001_sync", "2011_09_26_drive_0002_sync"])
        self.assertIn("--no-osm", self.tool_calls("offline_slam")[0])  # no prior beside a real drive

    def test_finished_drives_are_not_run_again_and_no_map_is_status_1(self):
        status, text, doc = self.simulate(1)
        self.assertEqual(status, 0, text)
        status, text, doc = self.simulate(2)
        self.assertEqual(status, 0, text)
        self.assertEqual([s["status"] for s in doc["sessions"]], ["finished before", "ok"])
        self.assertEqual(self.offline_slam_drives(), ["sim_w4_s1", "sim_w4_s2"])
        os.environ["FAKE_FAIL"] = "sim_w4_s1"
        status, text, doc = self.simulate(1, "--force")
        self.assertEqual(status, 1, text)
        self.assertFalse(doc["map"]["made"])
        self.assertIn("NO MAP: no session to merge", text)

    def test_bad_input_is_status_2_before_any_cluster(self):
        status, text, _ = self.fleet("--simulate", "2")
        self.assertEqual(status, 2)
        self.assertIn("--simulate needs --world-seed and --prior-seed", text)
        status, text, _ = self.fleet("--dumps", os.path.join(self.tmp, "nowhere"))
        self.assertEqual(status, 2)
        self.assertIn("not a folder", text)


@NEEDS_DASK
class WorkerPathTest(unittest.TestCase):
    def test_the_plugin_puts_scripts_on_every_worker_s_path(self):
        client, local = cluster.connect(workers=2)
        try:
            # Spawned workers inherit this process's path: take scripts/ away to see the plugin
            # put it back, as it does on workers started by hand.
            client.run(lambda folder: sys.path.remove(folder) if folder in sys.path else None, SCRIPTS)
            self.assertFalse(any(client.run(lambda folder: folder in sys.path, SCRIPTS).values()))
            cluster.put_scripts_on_workers(client)
            self.assertEqual(list(client.run(lambda folder: folder in sys.path, SCRIPTS).values()), [True, True])
        finally:
            cluster.close(client, local)

    def test_default_workers(self):
        self.assertEqual([cluster.default_workers(c) for c in (1, 2, 8)], [1, 2, 8])


class FleetPackageLayoutTest(unittest.TestCase):
    def test_each_module_imports_only_those_listed_above_it(self):
        # As drive_matrix: the package's docstring lists the modules in dependency order.
        package = os.path.join(SCRIPTS, "fleet")
        with open(os.path.join(package, "__init__.py")) as f:
            order = re.findall(r"^    (\w+)\.py ", f.read(), re.M)
        modules = sorted(f for f in os.listdir(package) if f.endswith(".py") and f != "__init__.py")
        self.assertEqual(sorted(n + ".py" for n in order), modules)
        for i, name in enumerate(order):
            with open(os.path.join(package, name + ".py")) as f:
                text = f.read()
            self.assertLessEqual(text.count("\n"), 300, name)
            for other in re.findall(r"^from \.(\w+) import|^from \. import (\w+)", text, re.M):
                other = other[0] or other[1]
                self.assertIn(other, order[:i], "%s.py imports %s.py, listed below it" % (name, other))


@NEEDS_DASK
class MatrixOnDaskTest(MatrixFakeTools, unittest.TestCase):
    def test_rows_are_the_thread_pool_s(self):
        drives = [Drive(World("city"), s, 100) for s in (1, 2, 3)]
        ctx = Context(self.bin, self.config, self.out, [])

        def runner(drive, ctx):  # defined in a function: Dask sends it by value
            if drive.seed == 2:
                raise RuntimeError("runner bug")
            return drive_row(drive, "ok", {"ate_m": 0.1 * drive.seed}, {"simulate": 1.0})

        quiet = lambda *_: None  # noqa: E731
        threads = run_matrix(drives, ctx, drives, 2, runner=runner, log=quiet)
        dask = run_matrix(drives, ctx, drives, 2, runner=runner, log=quiet, executor="dask")
        self.assertEqual(dask, threads)
        self.assertEqual(dask[drives[1]]["status"], "error: internal: RuntimeError: runner bug")

    def test_whole_drives_with_the_fake_tools(self):
        status, text = self.matrix("--world", "city", "--seed", "1,2", "--length", "100", "--executor", "dask",
                                   "--jobs", "2")
        self.assertEqual(status, 0, text)
        self.assertEqual([self.result(n)["status"] for n in ("city_s1_100m_independent_hdl64e_noisy",
                                                             "city_s2_100m_independent_hdl64e_noisy")], ["ok", "ok"])
        self.assertIn("[matrix] 2/2 ", text)


if __name__ == "__main__":
    unittest.main()

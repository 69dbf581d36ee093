"""Tests of the drive matrix's GNSS modes (noisy, rtk, canyon, origin) and its three SLAM runs
(with OSM, the GNSS baseline without it, odometry + loops), without the real tools: the flags
of each mode, the runs' commands (and the run an 'origin' drive leaves out), their replay, an
older build without --gnss, the table's and the per-mode summary's columns, and a stored
result.json from before the third run.

    /usr/bin/python3 -m unittest discover -s test/scripts -p '*_test.py'     (from the repo root)
"""
import json
import os
import unittest

# matrix_fakes loads the entry point, which puts scripts/ on the module path for drive_matrix.
from matrix_fakes import FakeTools, preset_drives, run_main

from drive_matrix.drives import GNSS_MODES, Drive, World
from drive_matrix.evaluation import odometry_metrics, parse_metrics
from drive_matrix.mode_summary import format_mode_summary, summarize_modes
from drive_matrix.table import format_table, summarize, worst_drive

CITY = World("city")
KARLSRUHE = World("karlsruhe", "/data/k.osm")
NO_GNSS = ["--gnss", "origin"]


class ModeFlagsTest(unittest.TestCase):
    def test_simulator_flags_of_each_mode(self):
        self.assertEqual(GNSS_MODES, ("noisy", "rtk", "canyon", "origin"))
        expected = {("city", "noisy"): [], ("city", "rtk"): ["--rtk"],
                    ("city", "canyon"): ["--gnss-model", "canyon", "--downtown"],
                    ("city", "origin"): ["--downtown"],  # noisy fixes on the canyon drives' streets
                    ("karlsruhe", "noisy"): [], ("karlsruhe", "rtk"): ["--rtk"],
                    ("karlsruhe", "canyon"): ["--gnss-model", "canyon"],  # an OSM world has no downtown
                    ("karlsruhe", "origin"): []}
        for (world, gnss), flags in expected.items():
            d = Drive(CITY if world == "city" else KARLSRUHE, 1, 300, gnss=gnss)
            self.assertEqual(d.new_flags(), flags, (world, gnss))
            self.assertTrue(d.name.endswith("_" + gnss), d.name)
        d = Drive(KARLSRUHE, 2, 300, gnss="canyon")
        self.assertEqual(d.sim_flags(), ["--seed", "2", "--length", "300", "--osm", "/data/k.osm",
                                         "--gnss-model", "canyon"])

    def test_three_runs_and_two_on_an_origin_drive(self):
        runs = Drive(CITY, 1, 300, gnss="canyon").slam_runs()
        self.assertEqual([(r.name, r.with_osm, list(r.flags)) for r in runs],
                         [("slam_osm", True, []), ("slam_no_osm", False, []), ("slam_odom", False, NO_GNSS)])
        self.assertEqual([r.title for r in runs], ["(with OSM)", "--no-osm", "--no-osm --gnss origin"])
        runs = Drive(CITY, 1, 300, gnss="origin").slam_runs()
        self.assertEqual([(r.name, r.with_osm, list(r.flags)) for r in runs],
                         [("slam_osm", True, NO_GNSS), ("slam_no_osm", False, NO_GNSS)])
        # the time estimate counts the runs
        noisy, origin = Drive(CITY, 1, 300), Drive(CITY, 1, 300, gnss="origin")
        self.assertAlmostEqual(noisy.estimated_seconds() - origin.estimated_seconds(), 560 / 19.0)

    def test_gnss_axis_selects_the_modes(self):
        status, text = run_main(["--world", "city", "--gnss", "canyon,origin", "--list"])
        self.assertEqual(status, 0, text)
        self.assertIn("city_s1_300m_independent_hdl64e_canyon", text)
        self.assertIn("--gnss-model canyon --downtown", text)
        self.assertIn("2 drives", text)
        status, text = run_main(["--world", "city", "--gnss", "tunnel", "--list"])
        self.assertEqual(status, 2)
        self.assertIn("unknown GNSS mode 'tunnel'", text)


class PresetTest(unittest.TestCase):
    def test_default_preset_has_the_new_modes_on_both_worlds(self):
        drives = preset_drives("default")
        for mode in ("canyon", "origin"):
            for world in ("karlsruhe", "city"):
                mine = [d for d in drives if d.gnss == mode and d.world.label == world]
                self.assertGreaterEqual(len({d.seed for d in mine}), 3, (mode, world))
                self.assertEqual({d.length for d in mine}, {300})
        rtk = [d for d in drives if d.gnss == "rtk"]
        self.assertEqual(len(rtk), 4)
        # the rtk drives have noisy twins: the same drive with the consumer-grade fixes
        names = {d.name for d in drives}
        self.assertTrue(all(d.name[: -len("rtk")] + "noisy" in names for d in rtk))
        self.assertEqual(len(drives), 28 + 12 + 4)
        # the time estimate: under 3 h by the (pessimistic) model; doc/matrix.md has the measured
        self.assertLess(sum(d.estimated_seconds() for d in drives), 3 * 3600)

    def test_gnss_preset_and_selecting_one_mode(self):
        drives = preset_drives("gnss")
        self.assertEqual(len(drives), 16)
        default = set(preset_drives("default"))
        new = [d for d in drives if d.gnss != "noisy"]
        self.assertEqual(len(new), 12)
        self.assertTrue(set(new) <= default)  # a default run reuses them (and vice versa)
        self.assertEqual({d.gnss for d in drives}, {"noisy", "canyon", "origin"})
        origin = preset_drives("gnss", ["--gnss", "origin"])
        self.assertEqual(len(origin), 6)
        self.assertEqual({d.gnss for d in origin}, {"origin"})
        self.assertLess(sum(d.estimated_seconds() for d in drives), 45 * 60)


class ThreeRunsTest(FakeTools, unittest.TestCase):
    def slam_calls(self, tool="offline_slam"):
        return [c for c in self.tool_calls() if c[0] == tool]

    def test_canyon_drive_runs_three_and_evaluates_the_third(self):
        status, text = self.matrix("--world", "city", "--length", "100", "--gnss", "canyon", "--dump")
        self.assertEqual(status, 0, text)
        d = os.path.join(self.out, "city_s1_100m_independent_hdl64e_canyon")
        sim = [c for c in self.tool_calls() if c[0] == "simulate_urban"][0]
        self.assertEqual(sim[sim.index("--gnss-model"):sim.index("--gnss-model") + 3],
                         ["--gnss-model", "canyon", "--downtown"])
        slam = self.slam_calls()
        self.assertEqual([c[c.index("--output") + 1] for c in slam],
                         [os.path.join(d, r) for r in ("slam_osm", "slam_no_osm", "slam_odom")])
        self.assertIn("--osm", slam[0])
        self.assertEqual([("--no-osm" in c, "--gnss" in c) for c in slam], [(False, False), (True, False), (True, True)])
        self.assertEqual(slam[2][slam[2].index("--gnss") + 1], "origin")
        self.assertEqual(slam[2][slam[2].index("--dump") + 1], os.path.join(d, "slam_odom", "dump"))
        evals = [c for c in self.tool_calls() if c[0] == "evaluate_slam" and "--help" not in c]
        self.assertEqual(len(evals), 2)
        self.assertEqual(evals[0][evals[0].index("--baseline-label") + 1], "gnss")
        self.assertEqual(evals[1][evals[1].index("--estimate") + 1], os.path.join(d, "slam_odom", "trajectory_tum.txt"))
        self.assertEqual(evals[1][evals[1].index("--ground-truth") + 1], evals[0][evals[0].index("--ground-truth") + 1])
        self.assertNotIn("--baseline", evals[1])
        for f in ("logs/offline_slam_odom.log", "logs/evaluate_slam_odom.log", "evaluation_odom.json"):
            self.assertTrue(os.path.exists(os.path.join(d, f)), f)
        m = self.result("city_s1_100m_independent_hdl64e_canyon")["metrics"]
        self.assertEqual((m["ate_odom"], m["ate_no_osm"], m["ate_osm"]), (0.3, 0.2, 0.12))
        self.assertAlmostEqual(m["ate_change_pct"], -40.0)
        self.assertAlmostEqual(m["ate_change_odom_pct"], -60.0)
        self.assertEqual((m["odom_run"], m["baseline"], m["rpe_odom"]), ("slam_odom", "gnss", 0.007))
        self.assertIn("vs gnss median -40.0 %", text)

    def test_origin_drive_runs_two_both_without_gnss(self):
        status, text = self.matrix("--world", "karlsruhe", "--length", "100", "--gnss", "origin")
        self.assertEqual(status, 0, text)
        name = "karlsruhe_s1_100m_independent_hdl64e_origin"
        sim = [c for c in self.tool_calls() if c[0] == "simulate_urban"][0]
        self.assertFalse({"--downtown", "--gnss-model", "--rtk"} & set(sim))
        slam = self.slam_calls()
        self.assertEqual([os.path.basename(c[c.index("--output") + 1]) for c in slam], ["slam_osm", "slam_no_osm"])
        self.assertTrue(all(c[c.index("--gnss"):c.index("--gnss") + 2] == NO_GNSS for c in slam))
        evals = [c for c in self.tool_calls() if c[0] == "evaluate_slam" and "--help" not in c]
        self.assertEqual(len(evals), 1)
        self.assertEqual(evals[0][evals[0].index("--baseline-label") + 1], "odom+loops")
        self.assertFalse(os.path.exists(os.path.join(self.out, name, "slam_odom")))
        m = self.result(name)["metrics"]
        self.assertEqual((m["ate_odom"], m["ate_no_osm"], m["rpe_odom"]), (0.2, 0.2, 0.005))
        self.assertAlmostEqual(m["ate_change_odom_pct"], m["ate_change_pct"])
        self.assertEqual((m["odom_run"], m["baseline"]), ("slam_no_osm", "odom+loops"))
        self.assertIn("[matrix] origin, 1 drives: ATE with OSM median 0.120 m", text)
        self.assertIn("vs odom+loops median -40.0 %", text)
        self.assertIn("ATE change -40.0 % vs odom+loops", text)

    def test_replay_of_all_runs_and_of_a_matrix_dumped_before_the_third(self):
        status, text = self.matrix("--world", "city", "--length", "100", "--gnss", "noisy,origin", "--dump")
        self.assertEqual(status, 0, text)
        src = os.path.join(self.out, "city_s1_100m_independent_hdl64e_noisy")
        os.remove(self.calls)
        replay_out = os.path.join(self.tmp, "replay")
        argv = ["--bin", self.bin, "--out", replay_out, "--config", self.config, "--world", "city",
                "--length", "100", "--gnss", "noisy,origin", "--replay", self.out, "--set", "k=1"]
        status, text = run_main(argv)
        self.assertEqual(status, 0, text)
        replays = self.slam_calls("replay_backend")
        self.assertEqual([c[c.index("--dump") + 1].split(os.sep)[-3:-1] for c in replays],
                         [[src.split(os.sep)[-1], r] for r in ("slam_osm", "slam_no_osm", "slam_odom")]
                         + [["city_s1_100m_independent_hdl64e_origin", r] for r in ("slam_osm", "slam_no_osm")])
        flags = [[a for a in c if a in ("--no-osm", "--gnss", "origin")] for c in replays]
        self.assertEqual(flags, [[], ["--no-osm"], ["--no-osm", "--gnss", "origin"],
                                 ["--gnss", "origin"], ["--no-osm", "--gnss", "origin"]])
        self.assertTrue(all(c[-2:] == ["--set", "k=1"] for c in replays))
        doc = json.load(open(os.path.join(replay_out, "matrix.json")))
        self.assertEqual([r["metrics"]["ate_odom"] for r in doc["drives"]], [0.3, 0.2])
        # a matrix dumped before slam_odom existed: the other two runs are replayed, the third is noted
        import shutil
        shutil.rmtree(os.path.join(src, "slam_odom"))
        status, text = run_main(argv + ["--force"])
        self.assertEqual(status, 0, text)
        r = json.load(open(os.path.join(replay_out, "matrix.json")))["drives"][0]
        self.assertEqual(r["status"], "ok")
        self.assertIsNone(r["metrics"]["ate_odom"])
        self.assertEqual(r["metrics"]["ate_osm"], 0.12)
        self.assertIn("not replayed", r["metrics"]["notes"][0])

    def test_a_build_without_the_gnss_option_says_so(self):
        os.environ["FAKE_NO_GNSS_OPTION"] = "1"
        status, text = self.matrix("--world", "city", "--length", "100", "--gnss", "noisy,origin")
        self.assertEqual(status, 0, text)
        by = {r["gnss"]: r["status"] for r in json.load(open(os.path.join(self.out, "matrix.json")))["drives"]}
        self.assertEqual(by["noisy"], "error: offline_slam --no-osm --gnss origin: offline_slam does not know "
                                      "--gnss (printed its usage; not built yet?)")
        self.assertEqual(by["origin"], "error: offline_slam (with OSM) --gnss origin: offline_slam does not know "
                                       "--gnss (printed its usage; not built yet?)")


def row(name, gnss, **metrics):
    return {"drive": name, "world": "city", "seed": 1, "length_m": 300, "prior_model": "independent",
            "sensor": "hdl64e", "gnss": gnss, "status": "ok", "metrics": metrics}


class TableAndSummaryTest(unittest.TestCase):
    def test_table_has_the_three_runs_and_both_changes(self):
        rows = [row("a", "canyon", fix_rms=9.9, ate_odom=3.0, ate_no_osm=2.0, ate_osm=1.5, ate_change_pct=-25.0,
                    ate_change_odom_pct=-50.0)]
        lines = format_table(rows, summarize(rows)).splitlines()
        head = lines[0].split()
        for h in ("fixRMS", "ATE_odo", "ATE_gns", "ATE_osm", "chgGns%", "chgOdo%"):
            self.assertIn(h, head)
        i = head.index("ATE_odo")
        self.assertEqual(head[i:i + 5], ["ATE_odo", "ATE_gns", "ATE_osm", "chgGns%", "chgOdo%"])
        self.assertIn("3.000   2.000   1.500   -25.0   -50.0", lines[1])
        self.assertIn(" canyon ", lines[1])

    def test_summary_per_mode_against_its_baseline(self):
        rows = [row("n1", "noisy", ate_osm=1.0, ate_change_pct=-5.0, ate_change_odom_pct=-30.0, seen_shape=0.2,
                    seen_corrected=0.8, offset_bound=0.5),
                row("n2", "noisy", ate_osm=2.0, ate_change_pct=1.0, ate_change_odom_pct=-20.0, seen_shape=0.1,
                    seen_corrected=0.6, offset_bound=0.5),
                row("o1", "origin", ate_osm=3.0, ate_change_pct=-35.0, ate_change_odom_pct=-35.0),
                row("o2", "origin", ate_osm=4.0, ate_change_pct=2.5, ate_change_odom_pct=2.5),
                dict(row("o3", "origin", ate_osm=99.0, ate_change_odom_pct=99.0), status="error: x")]
        s = summarize_modes(rows)
        self.assertEqual(list(s), ["noisy", "origin"])
        self.assertEqual((s["noisy"]["drives"], s["noisy"]["baseline"]), (2, "gnss"))
        self.assertEqual((s["origin"]["drives"], s["origin"]["baseline"]), (2, "odom+loops"))
        self.assertAlmostEqual(s["noisy"]["ate_change_pct"]["median"], -2.0)  # vs GNSS, not vs odometry
        self.assertEqual((s["noisy"]["ate_change_pct"]["worst"], s["noisy"]["ate_change_pct"]["worst_drive"]), (1.0, "n2"))
        self.assertEqual((s["origin"]["ate_osm"]["worst"], s["origin"]["ate_osm"]["worst_drive"]), (4.0, "o2"))
        self.assertAlmostEqual(s["noisy"]["seen_shape"]["median"], 0.15)
        self.assertAlmostEqual(s["noisy"]["corner_error_over_bound"], 0.7 / 0.5)
        self.assertIsNone(s["origin"]["corner_error_over_bound"])
        lines = format_mode_summary(s)
        self.assertEqual(lines[0], "[matrix] noisy, 2 drives: ATE with OSM median 1.500 m, worst 2.000 m (n2); "
                                   "vs gnss median -2.0 %, worst +1.0 % (n2); S_shp median 0.15 m; "
                                   "S_corr median 0.70 m = 1.40 x B_bnd median 0.50 m")
        self.assertIn("vs odom+loops median -16.2 %, worst +2.5 % (o2); S_shp median - m", lines[1])
        self.assertEqual(worst_drive(rows)[1][:40], "ATE change +2.5 % vs odom+loops (ATE 4.0")

    def test_a_result_from_before_the_third_run(self):
        # A stored row of an older matrix: no odometry + loops numbers, no fix statistics.
        old = row("old", "noisy", ate_osm=0.9, ate_no_osm=1.0, ate_change_pct=-10.0, seen_shape=0.2)
        rows = [old, row("new", "noisy", ate_odom=1.2, ate_osm=0.9, ate_no_osm=1.0, ate_change_pct=-10.0,
                         ate_change_odom_pct=-25.0)]
        summary = summarize(rows)
        self.assertEqual(summary["ate_odom"]["count"], 1)
        lines = format_table(rows, summary).splitlines()
        head = lines[0].split()
        cells = lines[1].split()  # one word per column: the status is "ok"
        self.assertEqual(len(cells), len(head))
        self.assertEqual([cells[head.index(h)] for h in ("ATE_odo", "ATE_gns", "ATE_osm", "chgGns%", "chgOdo%")],
                         ["-", "1.000", "0.900", "-10.0", "-"])
        self.assertEqual(format_mode_summary(summarize_modes(rows))[0][:30], "[matrix] noisy, 2 drives: ATE ")

    def test_the_third_runs_numbers_and_the_fixes(self):
        m = parse_metrics({"slam": {"ate_m": {"mean": 1.0}}, "gnss": {"ate_m": {"mean": 2.0}}}, None, None,
                          {"gnss_ins": {"model": "canyon", "gnss_error_rms_m": 9.9, "nlos_fix_share": 0.66,
                                        "first_fix_error_enu_m": [3.0, 4.0, 9.0]}})
        self.assertEqual((m["ate_no_osm"], m["ate_change_pct"]), (2.0, -50.0))
        self.assertEqual((m["fix_rms"], m["fix_nlos_share"], m["first_fix_error"], m["fix_p95"]), (9.9, 0.66, 5.0, None))
        o = odometry_metrics(m, {"slam": {"ate_m": {"mean": 4.0}}}, "canyon")
        self.assertEqual((o["ate_odom"], o["ate_change_odom_pct"], o["odom_run"]), (4.0, -75.0, "slam_odom"))
        o = odometry_metrics(m, None, "noisy")  # not run (a replay without its dump)
        self.assertEqual((o["ate_odom"], o["ate_change_odom_pct"], o["odom_run"]), (None, None, None))
        o = odometry_metrics(m, None, "origin")
        self.assertEqual((o["ate_odom"], o["ate_change_odom_pct"], o["odom_run"]), (2.0, -50.0, "slam_no_osm"))


if __name__ == "__main__":
    unittest.main()

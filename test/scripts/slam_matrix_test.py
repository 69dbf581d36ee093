"""Tests of scripts/slam_matrix.py and its package scripts/drive_matrix without the real tools:
the grid of each preset, summary, check limits, result parsing with missing keys, resume, whole
drives run with fake simulate_urban / offline_slam / evaluate_slam programs (small Python scripts
in a temporary bin folder: matrix_fakes.py), and the entry point and the package's layout.
The GNSS modes and the three SLAM runs: slam_matrix_gnss_test.py.

    /usr/bin/python3 -m unittest discover -s test/scripts -p '*_test.py'     (from the repo root)
"""
import json
import math
import os
import shutil
import re
import subprocess
import sys
import tempfile
import unittest

# matrix_fakes loads the entry point, which puts scripts/ on the module path for drive_matrix.
from matrix_fakes import PACKAGE, REPO, SCRIPT, FakeTools, preset_drives, run_main, sm

from drive_matrix.drives import (KARLSRUHE, PRIOR_MODELS, SENSORS, Drive, MatrixError, World,
                                 parse_burst, parse_world)
from drive_matrix.evaluation import parse_metrics
from drive_matrix.ground_truth import kitti_stamp_ns, stamp_text, write_full_ground_truth
from drive_matrix.grid import axes_from_args, build_grid
from drive_matrix.one_drive import drive_row
from drive_matrix.own_metrics import (absolute_offset_metrics, gnss_mean_error, offset_bound,
                                      orientation_metrics, own_coverage, quat_conj, quat_mul)
from drive_matrix.scheduler import plan, run_matrix
from drive_matrix.table import check_rows, format_table, summarize, worst_drive
from drive_matrix.tools import Context

class GridTest(unittest.TestCase):
    def test_default_preset_is_balanced(self):
        # The noisy drives (the matrix before the GNSS modes, kept so that results stay
        # comparable); the other modes: slam_matrix_gnss_test.py.
        drives = [d for d in preset_drives("default") if d.gnss == "noisy"]
        self.assertEqual(len(drives), 28)
        self.assertEqual(len({d.name for d in drives}), len(drives))
        worlds = {d.world.label for d in drives}
        self.assertEqual(worlds, {"karlsruhe", "city"})
        karlsruhe = [d for d in drives if d.world.label == "karlsruhe"][0]
        self.assertTrue(karlsruhe.world.path.endswith("shared/data/osm/2011_09_26_drive_0005_sync.osm"))
        for w in worlds:
            self.assertGreaterEqual(len({d.seed for d in drives if d.world.label == w}), 3)
        self.assertEqual({d.length for d in drives}, {300, 1500})
        self.assertEqual({d.prior_model for d in drives}, set(PRIOR_MODELS))
        self.assertEqual({d.sensor for d in drives}, set(SENSORS))
        # every prior model and sensor meets both worlds and both lengths
        for attr, values in (("prior_model", PRIOR_MODELS), ("sensor", SENSORS)):
            for v in values:
                mine = [d for d in drives if getattr(d, attr) == v]
                self.assertEqual({d.world.label for d in mine}, worlds, (attr, v))
                self.assertEqual({d.length for d in mine}, {300, 1500}, (attr, v))
        # each world and length has both worlds' seeds x lengths cells
        for w in worlds:
            for length in (300, 1500):
                self.assertGreaterEqual(len({d.seed for d in drives if d.world.label == w and d.length == length}), 3)
        # every (prior model, sensor) pair is measured
        self.assertEqual(len({(d.prior_model, d.sensor) for d in drives}), 8)

    def test_default_preset_has_drives_whose_map_is_shifted_as_a_whole(self):
        shifted = [d for d in preset_drives("default") if d.map_shift > 0]
        self.assertEqual(sorted((d.world.label, d.seed) for d in shifted),
                         [("city", 1), ("city", 4), ("karlsruhe", 1), ("karlsruhe", 4)])
        for d in shifted:
            self.assertEqual((d.prior_model, d.length, d.map_shift), ("global", 300, 1.5))
            self.assertIn("--prior-global-offset 1.5,1.5", " ".join(d.sim_flags()))
            self.assertTrue(d.name.endswith("_shift1.5"), d.name)
        # they belong to the preset's worlds, and give way to any other explicit axis
        drives = preset_drives("default", ["--world", "city"])
        self.assertEqual(len([d for d in drives if d.map_shift > 0]), 2)
        self.assertFalse(any(d.map_shift > 0 for d in preset_drives("default", ["--seed", "2"])))
        self.assertFalse(any(d.map_shift > 0 for d in preset_drives("quick")))

    def test_quick_preset(self):
        drives = preset_drives("quick")
        self.assertTrue(4 <= len(drives) <= 6)
        self.assertTrue(all(150 <= d.length <= 300 for d in drives))
        self.assertEqual({d.world.label for d in drives}, {"karlsruhe", "city"})
        self.assertEqual(len({d.prior_model for d in drives}), 2)
        self.assertLess(sum(d.estimated_seconds() for d in drives), 10 * 60)

    def test_stress_preset_has_manoeuvres_and_drops_and_a_control(self):
        drives = preset_drives("stress")
        self.assertTrue(any(d.manoeuvres != "none" for d in drives))
        self.assertTrue(any(d.drop_scans > 0 for d in drives))
        self.assertTrue(any(d.dropout_burst for d in drives))
        self.assertTrue(any(d.manoeuvres == "none" and d.drop_scans == 0 for d in drives))
        self.assertEqual({d.world.label for d in drives}, {"karlsruhe", "city"})

    def test_stress_scenarios_give_way_to_explicit_axes(self):
        self.assertEqual(len(preset_drives("stress")), 10)
        drives = preset_drives("stress", ["--manoeuvres", "sharp_turn"])
        self.assertEqual(len(drives), 8)
        self.assertEqual({d.manoeuvres for d in drives}, {"sharp_turn"})
        self.assertEqual({(d.drop_scans, d.dropout_burst) for d in drives}, {(0, 0), (0.05, 0), (0, 20), (0.05, 20)})

    def test_explicit_axes_replace_the_presets(self):
        drives = preset_drives("default", ["--sensor", "os1_64", "--seed", "7,8"])
        self.assertEqual({d.sensor for d in drives}, {"os1_64"})
        self.assertEqual({d.seed for d in drives}, {7, 8})
        self.assertEqual({d.prior_model for d in drives}, set(PRIOR_MODELS))
        drives = preset_drives("quick", ["--world", "city"])
        self.assertEqual({d.world.label for d in drives}, {"city"})

    def test_without_preset_the_product_of_the_axes(self):
        args = sm.build_parser().parse_args(["--world", "city", "--seed", "1,2", "--length", "100",
                                             "--length", "200", "--manoeuvres", "sharp_turn,stop"])
        drives = build_grid(*axes_from_args(args))
        self.assertEqual(len(drives), 4)
        self.assertEqual({d.manoeuvres for d in drives}, {"sharp_turn,stop"})

    def test_worlds_take_a_comma_list_like_the_other_axes(self):
        args = sm.build_parser().parse_args(["--world", "karlsruhe,city", "--seed", "1"])
        drives = build_grid(*axes_from_args(args))
        self.assertEqual(sorted(d.world.label for d in drives), ["city", "karlsruhe"])

    def test_bad_axis_values_are_one_clear_error(self):
        for argv in (["--seed", "x"], ["--prior-model", "banana"], ["--length", "0"], ["--drop-scans", "1.5"]):
            status, text = run_main(["--world", "city", "--list"] + argv)
            self.assertEqual(status, 2, argv)
            self.assertIn("slam_matrix: ", text)
            self.assertNotIn("Traceback", text)

    def test_flags_map_one_to_one_and_defaults_are_omitted(self):
        city = World("city")
        d = Drive(city, 1, 300)
        self.assertEqual(d.sim_flags(), ["--seed", "1", "--length", "300"])
        self.assertEqual(d.name, "city_s1_300m_independent_hdl64e_noisy")
        d = Drive(World("k", "/x.osm"), 2, 150, "global", "os1_64", "rtk", "sharp_turn,stop", 0.05, 5)
        self.assertEqual(d.sim_flags(), ["--seed", "2", "--length", "150", "--osm", "/x.osm", "--prior-model",
                                         "global", "--sensor", "os1_64", "--rtk", "--manoeuvres",
                                         "sharp_turn,stop", "--drop-scans", "0.05", "--dropout-burst", "5"])
        self.assertEqual(d.name, "k_s2_150m_global_os1_64_rtk_man-sharp_turn+stop_drop0.05_burst5")
        d = Drive(city, 1, 300, dropout_burst="20@30.5")
        self.assertEqual(d.sim_flags()[-2:], ["--dropout-burst", "20@30.5"])
        self.assertEqual(d.name, "city_s1_300m_independent_hdl64e_noisy_burst20at30.5")
        self.assertEqual(Drive(city, 1, 300, dropout_burst="0"), Drive(city, 1, 300))
        d = Drive(city, 1, 300, "mixed", map_shift="2")
        self.assertEqual(d.sim_flags()[-2:], ["--prior-global-offset", "2,2"])
        self.assertEqual(d.name, "city_s1_300m_mixed_hdl64e_noisy_shift2")
        self.assertNotEqual(d, Drive(city, 1, 300, "mixed"))
        args = sm.build_parser().parse_args(["--world", "city", "--prior-model", "global", "--map-shift", "0,1.5"])
        self.assertEqual([d.map_shift for d in build_grid(*axes_from_args(args))], [0.0, 1.5])
        with self.assertRaises(MatrixError):
            parse_burst("x@1")

    def test_world_specs(self):
        self.assertEqual(parse_world("city").path, None)
        self.assertEqual(parse_world("karlsruhe").label, "karlsruhe")
        self.assertEqual(parse_world(os.path.join(REPO, KARLSRUHE)).label, "karlsruhe")
        w = parse_world("berlin=/data/b.osm.pbf")
        self.assertEqual((w.label, w.path), ("berlin", "/data/b.osm.pbf"))
        self.assertEqual(parse_world("/data/kitti_00.osm").label, "kitti_00")


def row(name, status="ok", **metrics):
    return {"drive": name, "world": "city", "seed": 1, "length_m": 300, "prior_model": "global",
            "sensor": "hdl64e", "gnss": "noisy", "status": status, "metrics": metrics}


class SummaryAndCheckTest(unittest.TestCase):
    def test_median_and_worst_follow_the_bad_direction(self):
        rows = [row("a", coverage=1.0, ate_change_pct=-40.0, scans_per_s=20.0, false_loops=0),
                row("b", coverage=0.8, ate_change_pct=10.0, scans_per_s=15.0, false_loops=2),
                row("c", coverage=0.9, ate_change_pct=-10.0, scans_per_s=None),
                row("d", "error: simulate: boom", coverage=0.1, ate_change_pct=99.0)]
        s = summarize(rows)
        self.assertAlmostEqual(s["coverage"]["median"], 0.9)
        self.assertEqual((s["coverage"]["worst"], s["coverage"]["worst_drive"]), (0.8, "b"))
        self.assertEqual((s["ate_change_pct"]["worst"], s["ate_change_pct"]["worst_drive"]), (10.0, "b"))
        self.assertAlmostEqual(s["ate_change_pct"]["median"], -10.0)
        self.assertEqual(s["scans_per_s"]["worst"], 15.0)
        self.assertEqual(s["scans_per_s"]["count"], 2)
        self.assertEqual(s["false_loops"]["worst"], 2)
        self.assertIsNone(s["keyframes"]["median"])
        self.assertEqual(worst_drive(rows)[0], "b")
        table = format_table(rows, s)
        self.assertEqual(len(table.splitlines()), 1 + 4 + 2)
        self.assertIn("error: simulate: boom", table)
        self.assertIn("-", table.splitlines()[3])

    def test_check_names_the_drive_and_the_limit(self):
        rows = [row("good", ate_ratio=0.6, rpe_ratio=1.0, coverage=1.0, false_loops=0, bld_corrected=0.3),
                row("bad", ate_ratio=1.3, rpe_ratio=1.0, coverage=0.5, false_loops=0, bld_corrected=0.3),
                row("unmeasured", ate_ratio=0.9, rpe_ratio=1.0, bld_corrected=0.3)]
        limits = {"max_ate_ratio": 1.0, "min_coverage": 0.9, "max_rpe_ratio": None,
                  "max_false_loops": None, "max_building_error": 0.5}
        v = check_rows(rows, limits)
        self.assertEqual(len(v), 3, v)
        self.assertTrue(any(x.startswith("bad:") and "--max-ate-ratio 1" in x for x in v))
        self.assertTrue(any(x.startswith("bad:") and "--min-coverage 0.9" in x for x in v))
        self.assertTrue(any(x.startswith("unmeasured:") and "not measured" in x for x in v))
        self.assertEqual(check_rows(rows[:1], limits), [])
        v = check_rows([row("x", "error: evaluate: boom")], limits)
        self.assertEqual(v, ["x: did not finish (error: evaluate: boom)"])
        self.assertEqual(check_rows(rows, {}), [])


class ParseTest(unittest.TestCase):
    TODAY = {"slam": {"associated": 154, "ate_m": {"mean": 0.133}, "rpe_trans_m": {"mean": 0.006}},
             "odom+loops": {"ate_m": {"mean": 0.231}, "rpe_trans_m": {"mean": 0.006}},
             "ate_change_vs_odom+loops": -0.426,
             "buildings_prior": {"matched": 28, "mean_corner_error_m": 1.432, "overlapping_pairs": 10},
             "buildings_corrected": {"matched": 28, "mean_corner_error_m": 0.380, "overlapping_pairs": 0},
             "buildings_prior_observed": {"matched": 25, "mean_corner_error_m": 1.431},
             "buildings_corrected_observed": {"matched": 25, "mean_corner_error_m": 0.252,
                                              "mean_corner_error_shape_m": 0.118}}

    def test_todays_keys(self):
        m = parse_metrics(self.TODAY, {"keyframes": 154, "loops": 7, "scans_per_second": 21.0},
                             None, {"revisits": 3, "scans": 651})
        self.assertAlmostEqual(m["ate_change_pct"], -42.6)
        self.assertAlmostEqual(m["ate_ratio"], 0.133 / 0.231)
        self.assertAlmostEqual(m["rpe_ratio"], 1.0)
        self.assertEqual((m["bld_prior"], m["bld_corrected"]), (1.432, 0.380))
        self.assertEqual((m["seen_prior"], m["seen_corrected"], m["seen_matched"]), (1.431, 0.252, 25))
        self.assertEqual(m["seen_shape"], 0.118)
        self.assertEqual((m["overlaps"], m["overlaps_prior"]), (0, 10))
        self.assertEqual((m["keyframes"], m["loops"], m["revisits"]), (154, 7, 3))
        self.assertIsNone(m["recall"])
        self.assertIsNone(m["false_loops"])
        self.assertIsNone(m["coverage"])
        self.assertEqual(m["scans_per_s"], 21.0)

    def test_new_keys_win(self):
        ev = dict(self.TODAY, coverage={"fraction": 0.93, "longest_gap_s": 4.0, "untracked_scans": 12},
                  loops={"revisits": 10, "revisits_closed": 7, "recall": 0.7, "accepted": 9, "false": 1})
        m = parse_metrics(ev, {"loops": 99, "tracking": {"lost_events": 2}}, None, {"revisits": 3},
                             {"fraction": 0.5, "longest_gap_s": 9.0})
        self.assertEqual((m["coverage"], m["coverage_source"], m["longest_gap_s"]), (0.93, "evaluate_slam", 4.0))
        self.assertEqual((m["loops"], m["revisits"], m["recall"], m["false_loops"]), (9, 10, 0.7, 1))
        self.assertEqual(m["lost_events"], 2)

    def test_missing_everything_gives_none_not_an_exception(self):
        for ev in ({}, None, {"slam": {}}, {"slam": {"ate_m": "x"}, "odometry": {"ate_m": {"mean": 0}}}):
            m = parse_metrics(ev, None, "garbage", [])
            self.assertIsNone(m["ate_osm"])
            self.assertIsNone(m["ate_ratio"])
            self.assertIsNone(m["coverage"])
            format_table([row("x", **m)], summarize([row("x", **m)]))

    def test_other_baseline_label(self):
        ev = {"slam": {"ate_m": {"mean": 0.3}}, "odometry": {"ate_m": {"mean": 0.2}}}
        m = parse_metrics(ev)
        self.assertAlmostEqual(m["ate_change_pct"], 50.0)

    def test_own_coverage(self):
        c = own_coverage([2.0, 3.0, 8.0], [0.0, 10.0])
        self.assertAlmostEqual(c["fraction"], 0.6)
        self.assertAlmostEqual(c["longest_gap_s"], 5.0)
        self.assertEqual(own_coverage([], [0.0, 10.0])["fraction"], 0.0)
        self.assertIsNone(own_coverage([1.0], [5.0]))

    def test_offset_bound_is_the_nearest_point_between_the_two_references(self):
        self.assertAlmostEqual(offset_bound((2.0, 0.0), (-1.0, 0.0)), 0.0)  # opposite: they cancel
        self.assertAlmostEqual(offset_bound((1.2, 0.0), (1.6, 0.0)), 1.2)  # same way: the smaller
        self.assertAlmostEqual(offset_bound((1.0, 1.0), (1.0, -1.0)), 1.0)  # the segment's midpoint
        tmp = tempfile.mkdtemp(prefix="offset_bound_")
        try:
            drive = os.path.join(tmp, "drive")
            for sub in ("oxts", "oxts_true"):
                os.makedirs(os.path.join(drive, sub, "data"))
            lat, lon = 49.0, 8.4
            rows = [(1e-5, 1.8), (3e-5, 1.8), (9e-3, 1e4)]  # the third is an outage: not counted
            for i, (dlat, acc) in enumerate(rows):
                tail = " 0" * 15 + " %g" % acc + " 0" * 6 + "\n"  # pos_accuracy is field 23
                open(os.path.join(drive, "oxts", "data", "%010d.txt" % i), "w").write(
                    "%.9f %.9f 110 0 0 0 0 0" % (lat + dlat, lon) + tail[:-1] + "\n")
                open(os.path.join(drive, "oxts_true", "data", "%010d.txt" % i), "w").write(
                    "%.9f %.9f 110 0 0 0 0 0" % (lat, lon) + tail)
            east, north = gnss_mean_error(drive)
            self.assertAlmostEqual(east, 0.0, places=6)
            self.assertAlmostEqual(north, 2e-5 * math.pi / 180 * 6378137.0, places=4)  # 2.2 m
            open(os.path.join(tmp, "prior_offsets.csv"), "w").write(
                "# header\nosm_id,status,dx_m,dy_m,dtheta_deg,centroid_x,centroid_y\n"
                "1,moved,1.0,0.0,0,0,0\n2,moved,-3.0,0.0,0,0,0\n3,moved,9.0,9.0,0,0,0\n")
            feature = lambda i, n: {"properties": {"id": i, "tags": {"osm_graph_slam:observations": str(n)}}}
            geojson = os.path.join(tmp, "corrected.geojson")
            json.dump({"features": [feature(1, 4), feature(2, 1), feature(3, 0)]}, open(geojson, "w"))
            m = absolute_offset_metrics(tmp, drive, geojson)
            self.assertAlmostEqual(m["map_mean_offset"], 1.0)  # building 3 was never observed
            self.assertAlmostEqual(m["gnss_mean_error"], north, places=6)
            self.assertAlmostEqual(m["offset_bound"], offset_bound((-1.0, 0.0), (0.0, north)))
            self.assertEqual(absolute_offset_metrics(tmp, os.path.join(tmp, "none"), geojson)["offset_bound"], None)
            # an 'origin' drive's runs have the first fix only (1.1 m north)
            self.assertAlmostEqual(gnss_mean_error(drive, first_only=True)[1], north / 2, places=6)
            m = absolute_offset_metrics(tmp, drive, geojson, first_fix_only=True)
            self.assertAlmostEqual(m["offset_bound"], offset_bound((-1.0, 0.0), (0.0, north / 2)))
        finally:
            shutil.rmtree(tmp)

    def test_orientation_metrics(self):
        def q(axis, deg):  # (qx, qy, qz, qw) of a rotation about x, y or z
            h = math.radians(deg) / 2
            v = [0.0, 0.0, 0.0]
            v["xyz".index(axis)] = math.sin(h)
            return tuple(v) + (math.cos(h),)

        def write(path, quats):
            with open(path, "w") as f:
                f.write("# time tx ty tz qx qy qz qw\n")
                for i, r in enumerate(quats):
                    f.write("%.1f %d 0 0 %.12f %.12f %.12f %.12f\n" % ((100 + i * 0.1, i) + r))

        with tempfile.TemporaryDirectory() as tmp:
            osm, no_osm = os.path.join(tmp, "osm"), os.path.join(tmp, "no")
            os.makedirs(osm)
            os.makedirs(no_osm)
            truth = [quat_mul(q("z", 90.0), q("y", 2.0 * ((i + 1) % 2))) for i in range(5)]
            # Heading 1, 2, 3, 4, 5 deg off; the truth's own 2 deg pitch steps are no tilt error.
            write(os.path.join(osm, "trajectory_tum.txt"),
                  [quat_mul(q("z", i + 1.0), t) for i, t in enumerate(truth)])
            write(os.path.join(osm, "ground_truth_tum.txt"), truth)
            # Raw odometry from the identity, tilting 0, 3, 6, 9, 12 deg about its own x axis.
            write(os.path.join(no_osm, "odometry_tum.txt"),
                  [quat_mul(quat_conj(truth[0]), quat_mul(t, q("x", 3.0 * i)))
                   for i, t in enumerate(truth)])
            write(os.path.join(no_osm, "ground_truth_tum.txt"), truth)
            m = orientation_metrics(osm, no_osm)
            self.assertAlmostEqual(m["heading_deg"], 3.0, places=6)
            self.assertAlmostEqual(m["heading_max_deg"], 5.0, places=6)
            self.assertAlmostEqual(m["odo_tilt_deg"], 12.0, places=6)
            # Missing files: no numbers, no exception.
            m = orientation_metrics(os.path.join(tmp, "x"), os.path.join(tmp, "y"))
            self.assertIsNone(m["heading_deg"])
            self.assertIsNone(m["odo_tilt_deg"])

    def test_kitti_stamps(self):
        self.assertEqual(kitti_stamp_ns("2020-01-01 12:00:00.1"), 1577880000 * 10**9 + 100000000)
        self.assertEqual(stamp_text(1577880000 * 10**9 + 5), "1577880000.000000005")
        with self.assertRaises(ValueError):
            kitti_stamp_ns("yesterday")

    def test_ground_truth_moves_into_the_first_fix_frame(self):
        with tempfile.TemporaryDirectory() as tmp:
            sim = os.path.join(tmp, "sim")
            drive = os.path.join(sim, "d")
            os.makedirs(os.path.join(drive, "oxts", "data"))
            os.makedirs(os.path.join(sim, "ground_truth"))
            json.dump({"enu_origin": {"lat": 49.0, "lon": 8.4, "alt": 110.0}}, open(os.path.join(sim, "sim_info.json"), "w"))
            # the first fix 0.001 deg (111.2 m) north of the simulator's origin
            # the first record is in an outage (no fix): the map origin is the next one
            no_fix = ["48.0", "8.0", "100.0"] + ["0"] * 20 + ["10000"] + ["0"] * 6
            open(os.path.join(drive, "oxts", "data", "0000000000.txt"), "w").write(" ".join(no_fix) + "\n")
            open(os.path.join(drive, "oxts", "data", "0000000001.txt"), "w").write("49.001 8.4 110.0 0 0 0\n")
            open(os.path.join(drive, "oxts", "timestamps.txt"), "w").write(
                "2020-01-01 12:00:00.000000000\n2020-01-01 12:00:00.100000000\n")
            c, s = math.cos(0.3), math.sin(0.3)
            open(os.path.join(sim, "ground_truth", "poses_imu.txt"), "w").write(
                "1 0 0 0 0 1 0 0 0 0 1 0\n%r %r 0 10 %r %r 0 5 0 0 1 1\n" % (c, -s, s, c))
            out = os.path.join(tmp, "gt.txt")
            self.assertEqual(write_full_ground_truth(sim, drive, out), 2)
            rows = [list(map(float, line.split())) for line in open(out)]
            self.assertAlmostEqual(rows[0][0], 1577880000.0)
            self.assertAlmostEqual(rows[1][0] - rows[0][0], 0.1, places=6)
            self.assertAlmostEqual(rows[0][1], 0.0, places=2)
            self.assertAlmostEqual(rows[0][2], -111.2, delta=0.2)
            # rigid: the step between the poses keeps its length
            self.assertAlmostEqual(math.dist(rows[0][1:4], rows[1][1:4]), math.hypot(10, 5, 1), places=4)
            qz, qw = rows[1][6], rows[1][7]
            self.assertAlmostEqual(2 * math.atan2(qz, qw), 0.3, places=4)


class RunTest(FakeTools, unittest.TestCase):
    def test_drives_rows_resume_and_keep(self):
        status, text = self.matrix("--world", "city", "--seed", "1,2", "--length", "100", "--jobs", "2")
        self.assertEqual(status, 0, text)
        self.assertNotIn("Traceback", text)
        doc = json.load(open(os.path.join(self.out, "matrix.json")))
        self.assertEqual([r["status"] for r in doc["drives"]], ["ok", "ok"])
        m = doc["drives"][0]["metrics"]
        self.assertAlmostEqual(m["ate_change_pct"], -40.0)
        self.assertAlmostEqual(m["ate_ratio"], 0.6)
        self.assertEqual((m["keyframes"], m["loops"], m["revisits"]), (16, 4, 3))
        # no coverage from this evaluate_slam: the matrix's own, 0.2 .. 1.7 s of 0 .. 1.9 s
        self.assertAlmostEqual(m["coverage"], 1.5 / 1.9, places=3)
        self.assertIsNone(m["false_loops"])
        d = os.path.join(self.out, "city_s1_100m_independent_hdl64e_noisy")
        for f in ("result.json", "drive.json", "evaluation.json", "ground_truth_tum.txt",
                  "logs/simulate_urban.log", "logs/offline_slam_osm.log", "logs/offline_slam_no_osm.log",
                  "logs/evaluate_slam.log"):
            self.assertTrue(os.path.exists(os.path.join(d, f)), f)
        drive_dir = os.path.join(d, "sim", "2020_01_01", "2020_01_01_drive_0001_sync")
        self.assertFalse(os.path.exists(os.path.join(drive_dir, "velodyne_points")))
        self.assertTrue(os.path.exists(os.path.join(drive_dir, "oxts")))
        self.assertIn("worst drive:", text)
        self.assertIn("median", text)
        calls = self.tool_calls()
        sims = [c for c in calls if c[0] == "simulate_urban"]
        self.assertEqual(len(sims), 2)
        self.assertIn("--motion-distortion", sims[0])
        self.assertNotIn("--sensor", sims[0])
        slam = [c for c in calls if c[0] == "offline_slam"]
        self.assertEqual(len(slam), 6)  # with OSM, without (GNSS), odometry + loops
        self.assertTrue(all(c[c.index("--config") + 1] == self.config for c in slam))
        self.assertEqual(sum("--no-osm" in c for c in slam), 4)
        evals = [c for c in calls if c[0] == "evaluate_slam" and "--help" not in c]
        self.assertTrue(all("--run-report" not in c and "--loops" not in c for c in evals))

        # resume: nothing runs again; a new drive does
        os.remove(self.calls)
        status, text = self.matrix("--world", "city", "--seed", "1,2,3", "--length", "100")
        self.assertEqual(status, 0, text)
        sims = [c for c in self.tool_calls() if c[0] == "simulate_urban"]
        self.assertEqual([c[c.index("--seed") + 1] for c in sims], ["3"])
        self.assertIn("2 finished before, 1 to run", text)
        # --force runs everything; --keep keeps the scans
        os.remove(self.calls)
        status, text = self.matrix("--world", "city", "--seed", "1", "--length", "100", "--force", "--keep")
        self.assertEqual(len([c for c in self.tool_calls() if c[0] == "simulate_urban"]), 1)
        self.assertTrue(os.path.exists(os.path.join(drive_dir, "velodyne_points")))

    def test_replay_runs_only_the_back_ends_on_the_dumps(self):
        status, text = self.matrix("--world", "city", "--seed", "1", "--length", "100", "--dump")
        self.assertEqual(status, 0, text)
        src = os.path.join(self.out, "city_s1_100m_independent_hdl64e_noisy")
        slam = [c for c in self.tool_calls() if c[0] == "offline_slam"]
        dumps = [os.path.join(src, run, "dump") for run in ("slam_osm", "slam_no_osm", "slam_odom")]
        self.assertEqual([c[c.index("--dump") + 1] for c in slam], dumps)
        os.remove(self.calls)
        replay_out = os.path.join(self.tmp, "replay")
        scans = os.path.join(src, "sim", "2020_01_01", "2020_01_01_drive_0001_sync", "velodyne_points")
        os.makedirs(scans)  # as while the source's drive still runs (or was run with --keep)
        status, text = run_main(["--bin", self.bin, "--out", replay_out, "--config", self.config,
                                 "--world", "city", "--seed", "1,2", "--length", "100", "--replay", self.out,
                                 "--set", "gnss_prior_std=1.5", "--set", "osm_datum_std_xy=1"])
        self.assertEqual(status, 0, text)
        doc = json.load(open(os.path.join(replay_out, "matrix.json")))
        self.assertEqual(doc["drives"][0]["status"], "ok")
        self.assertAlmostEqual(doc["drives"][0]["metrics"]["ate_change_pct"], -40.0)
        self.assertIn("has no sim folder", doc["drives"][1]["status"])  # seed 2 was never run
        calls = self.tool_calls()
        self.assertFalse([c for c in calls if c[0] in ("simulate_urban", "offline_slam")])
        replays = [c for c in calls if c[0] == "replay_backend"]
        self.assertEqual([c[c.index("--dump") + 1] for c in replays], dumps)
        self.assertEqual(["--no-osm" in c for c in replays], [False, True, True])
        self.assertEqual(["--gnss" in c for c in replays], [False, False, True])
        for c in replays:
            self.assertEqual(c[-4:], ["--set", "gnss_prior_std=1.5", "--set", "osm_datum_std_xy=1"])
        d = os.path.join(replay_out, "city_s1_100m_independent_hdl64e_noisy")
        self.assertTrue(os.path.islink(os.path.join(d, "sim")))
        self.assertTrue(os.path.isfile(os.path.join(d, "slam_osm", "timing.json")))  # the front-end's
        # running the replay again replaces its own folders, never the source's simulation
        status, text = run_main(["--bin", self.bin, "--out", replay_out, "--config", self.config, "--force",
                                 "--world", "city", "--seed", "1", "--length", "100", "--replay", self.out])
        self.assertEqual(status, 0, text)
        self.assertTrue(os.path.isfile(os.path.join(src, "sim", "prior.osm")))
        self.assertTrue(os.path.isdir(scans))

    def test_new_evaluate_options_are_passed_when_known(self):
        os.environ["FAKE_NEW_EVAL"] = "1"
        status, text = self.matrix("--world", "city", "--length", "100")
        self.assertEqual(status, 0, text)
        evals = [c for c in self.tool_calls() if c[0] == "evaluate_slam" and "--baseline" in c]
        self.assertEqual(len(evals), 1)
        self.assertTrue(evals[0][evals[0].index("--run-report") + 1].endswith("slam_osm/timing.json"))
        self.assertTrue(evals[0][evals[0].index("--loops") + 1].endswith("slam_osm/loops.csv"))
        m = json.load(open(os.path.join(self.out, "matrix.json")))["drives"][0]["metrics"]
        self.assertEqual((m["coverage"], m["recall"], m["false_loops"], m["loops"]), (0.97, 0.8, 1, 6))
        status, text = self.matrix("--world", "city", "--length", "100", "--check", "--max-false-loops", "0")
        self.assertEqual(status, 1)
        self.assertIn("CHECK FAILED: city_s1_100m_independent_hdl64e_noisy: false loops 1.000 > --max-false-loops 0", text)
        status, text = self.matrix("--world", "city", "--length", "100", "--check", "--max-false-loops", "1",
                                   "--max-ate-ratio", "0.7", "--min-coverage", "0.9")
        self.assertEqual(status, 0, text)
        self.assertIn("check passed", text)

    def test_evaluation_falls_back_without_the_new_options(self):
        os.environ["FAKE_NEW_EVAL"] = "broken"
        status, text = self.matrix("--world", "city", "--length", "100")
        self.assertEqual(status, 0, text)
        r = json.load(open(os.path.join(self.out, "matrix.json")))["drives"][0]
        self.assertEqual(r["status"], "ok")
        self.assertIn("evaluated without them", r["metrics"]["notes"][0])
        evals = [c for c in self.tool_calls() if c[0] == "evaluate_slam" and "--baseline" in c]
        self.assertEqual(["--run-report" in c for c in evals], [True, False])

    def test_bad_input_gives_one_line_each_and_the_matrix_goes_on(self):
        missing = os.path.join(self.tmp, "nowhere.osm")
        status, text = self.matrix("--world", "city", "--world", "gone=" + missing, "--seed", "1,13,66",
                                   "--length", "100", "--check")
        self.assertEqual(status, 1)
        self.assertNotIn("Traceback", text)
        doc = json.load(open(os.path.join(self.out, "matrix.json")))
        by = {(r["world"], r["seed"]): r["status"] for r in doc["drives"]}
        self.assertEqual(by[("city", 1)], "ok")
        self.assertEqual(by[("gone", 1)], "error: world file missing: %s" % missing)
        self.assertEqual(by[("city", 13)],
                         "error: simulate: simulate_urban exited with status 1: "
                         "simulate_urban: cannot write scan 10: disk full")
        self.assertTrue(by[("city", 66)].startswith(
            "error: offline_slam --no-osm: offline_slam crashed (SIGSEGV): offline_slam: optimising"), by)
        self.assertIn("CHECK FAILED: gone_s1_100m", text)
        # a failed drive keeps its result (not run again) and loses its scans
        d66 = os.path.join(self.out, "city_s66_100m_independent_hdl64e_noisy")
        self.assertTrue(os.path.exists(os.path.join(d66, "result.json")))
        self.assertFalse(os.path.exists(os.path.join(d66, "sim", "2020_01_01", "2020_01_01_drive_0001_sync",
                                                     "velodyne_points")))
        os.remove(self.calls)
        self.matrix("--world", "city", "--seed", "66", "--length", "100")
        self.assertEqual([c for c in self.tool_calls() if c[0] == "simulate_urban"], [])
        self.matrix("--world", "city", "--seed", "66", "--length", "100", "--retry-failed")
        self.assertEqual(len([c for c in self.tool_calls() if c[0] == "simulate_urban"]), 1)

    def test_simulator_without_the_new_flags(self):
        os.environ["FAKE_OLD_SIM"] = "1"
        status, text = self.matrix("--world", "city", "--length", "100", "--prior-model", "independent,global")
        self.assertEqual(status, 0, text)
        by = {r["prior_model"]: r["status"] for r in json.load(open(os.path.join(self.out, "matrix.json")))["drives"]}
        self.assertEqual(by["independent"], "ok")
        self.assertEqual(by["global"], "error: simulate: simulate_urban does not know --prior-model "
                                       "(printed its usage; not built yet?)")

    def test_simulator_naming_the_flag_it_does_not_know(self):
        os.environ["FAKE_OLD_SIM"] = "names_it"
        status, text = self.matrix("--world", "city", "--length", "100", "--prior-model", "independent,global",
                                   "--gnss", "rtk")
        self.assertEqual(status, 0, text)
        by = {r["prior_model"]: r["status"] for r in json.load(open(os.path.join(self.out, "matrix.json")))["drives"]}
        self.assertEqual(by["global"], "error: simulate: simulate_urban does not know --prior-model "
                                       "(printed its usage; not built yet?)")

    def test_unwritable_output_and_missing_tools(self):
        blocker = os.path.join(self.tmp, "file")
        open(blocker, "w").write("")
        status, text = run_main(["--bin", self.bin, "--out", os.path.join(blocker, "sub"), "--world", "city"])
        self.assertEqual(status, 2)
        self.assertIn("slam_matrix: cannot write the output folder", text)
        self.assertNotIn("Traceback", text)
        status, text = run_main(["--bin", os.path.join(self.tmp, "nobin"), "--out", self.out, "--world", "city"])
        self.assertEqual(status, 2)
        self.assertIn("missing in", text)

    def test_unwritable_drive_folder_is_one_row(self):
        os.makedirs(self.out)
        open(os.path.join(self.out, "city_s1_100m_independent_hdl64e_noisy"), "w").write("")
        status, text = self.matrix("--world", "city", "--seed", "1,2", "--length", "100")
        self.assertEqual(status, 0, text)
        statuses = [r["status"] for r in json.load(open(os.path.join(self.out, "matrix.json")))["drives"]]
        self.assertTrue(statuses[0].startswith("error: cannot write "), statuses)
        self.assertEqual(statuses[1], "ok")

    def test_plan_skips_finished_drives(self):
        drives = [Drive(World("city"), s, 100) for s in (1, 2, 3)]
        for d, status in ((drives[0], "ok"), (drives[1], "error: x")):
            os.makedirs(os.path.join(self.out, d.name))
            json.dump(drive_row(d, status), open(os.path.join(self.out, d.name, "result.json"), "w"))
        to_run, stored = plan(drives, self.out)
        self.assertEqual(to_run, [drives[2]])
        self.assertEqual(set(stored), {drives[0], drives[1]})
        self.assertEqual(plan(drives, self.out, retry_failed=True)[0], drives[1:])
        self.assertEqual(plan(drives, self.out, force=True)[0], drives)

    def test_injected_runner(self):
        drives = [Drive(World("city"), s, 100) for s in (1, 2)]
        ctx = Context(self.bin, self.config, self.out, [])
        seen = []

        def runner(drive, ctx):
            seen.append(drive)
            if drive.seed == 2:
                raise RuntimeError("runner bug")
            return drive_row(drive, "ok", {"ate_change_pct": 1.0})

        results = run_matrix(drives, ctx, drives, 2, runner=runner, log=lambda *_: None)
        self.assertEqual(len(seen), 2)
        self.assertEqual(results[drives[0]]["status"], "ok")
        self.assertEqual(results[drives[1]]["status"], "error: internal: RuntimeError: runner bug")



class EntryPointAndLayoutTest(unittest.TestCase):
    def run_script(self, *argv):
        with tempfile.TemporaryDirectory() as cwd:  # not the repo: the script finds its package itself
            return subprocess.run([sys.executable, SCRIPT] + list(argv), cwd=cwd, stdin=subprocess.DEVNULL,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=60)

    def test_the_script_runs_as_a_program(self):
        p = self.run_script("--help")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("usage: slam_matrix.py", p.stdout)
        self.assertIn("--replay FROM", p.stdout)
        p = self.run_script("--world", "city", "--seed", "1,2", "--length", "300", "--list")
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertIn("city_s2_300m_independent_hdl64e_noisy", p.stdout)
        self.assertIn("2 drives", p.stdout)
        p = self.run_script("--world", "city", "--list", "--seed", "x")
        self.assertEqual((p.returncode, p.stdout), (2, ""))
        self.assertEqual(p.stderr, "slam_matrix: --seed takes a number, not 'x'\n")

    def modules(self):
        return sorted(f for f in os.listdir(PACKAGE) if f.endswith(".py") and f != "__init__.py")

    def test_modules_stay_small(self):
        for name in self.modules() + ["__init__.py"]:
            with open(os.path.join(PACKAGE, name)) as f:
                self.assertLessEqual(len(f.readlines()), 500, name)

    def test_each_module_imports_only_those_listed_above_it(self):
        # The package's docstring lists the modules in dependency order: a newcomer can read them
        # top down, and no import cycle can creep in.
        with open(os.path.join(PACKAGE, "__init__.py")) as f:
            order = re.findall(r"^    (\w+)\.py ", f.read(), re.M)
        self.assertEqual(sorted(n + ".py" for n in order), self.modules())
        for i, name in enumerate(order):
            with open(os.path.join(PACKAGE, name + ".py")) as f:
                imported = re.findall(r"^from \.(\w+) import", f.read(), re.M)
            for other in imported:
                self.assertIn(other, order[:i], "%s.py imports %s.py, listed below it" % (name, other))


if __name__ == "__main__":
    unittest.main()

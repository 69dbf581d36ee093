"""Tests of scripts/plot_map_overlay.py on a tiny synthetic output folder (binary and ascii
map.pcd, two buildings in the prior and corrected GeoJSON, origin.txt, a 10-pose trajectory):
the PNG is written and valid, corrupt or missing inputs give exit status 2 naming the file,
optional inputs are skipped with a note, and lat/lon -> ENU is right to centimetres.

    /usr/bin/python3 -m unittest discover -s test/scripts -p '*_test.py'     (from the repo root)
"""
import importlib.util
import json
import math
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import unittest

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
SCRIPT = os.path.join(REPO, "scripts", "plot_map_overlay.py")

spec = importlib.util.spec_from_file_location("plot_map_overlay", SCRIPT)
pmo = importlib.util.module_from_spec(spec)
spec.loader.exec_module(pmo)

ORIGIN = (49.011, 8.423, 112.0)  # lat, lon, alt (Karlsruhe, as KITTI)
WGS84_A, WGS84_F = 6378137.0, 1.0 / 298.257223563


def exact_enu(lat, lon, origin=ORIGIN):
    """East/north of a point on the ellipsoid (height 0) through ECEF: an independent reference."""
    e2 = WGS84_F * (2 - WGS84_F)

    def ecef(lat_deg, lon_deg):
        la, lo = math.radians(lat_deg), math.radians(lon_deg)
        n = WGS84_A / math.sqrt(1 - e2 * math.sin(la) ** 2)
        return np.array([n * math.cos(la) * math.cos(lo), n * math.cos(la) * math.sin(lo),
                         n * (1 - e2) * math.sin(la)])

    d = ecef(lat, lon) - ecef(origin[0], origin[1])
    la, lo = math.radians(origin[0]), math.radians(origin[1])
    east = -math.sin(lo) * d[0] + math.cos(lo) * d[1]
    north = (-math.sin(la) * math.cos(lo) * d[0] - math.sin(la) * math.sin(lo) * d[1]
             + math.cos(la) * d[2])
    return east, north


def to_lat_lon(east, north, origin=ORIGIN):
    """lat, lon whose exact ENU is (east, north): a few Newton steps with a spherical Jacobian."""
    r = 6371000.0
    lat, lon = origin[0], origin[1]
    for _ in range(5):
        e, n = exact_enu(lat, lon, origin)
        lat += math.degrees((north - n) / r)
        lon += math.degrees((east - e) / (r * math.cos(math.radians(origin[0]))))
    return lat, lon


BUILDINGS = {  # way id -> ENU rectangle corners (the corrected ones are 1.5 m east of the prior)
    4001: [(10, 12), (34, 12), (34, 26), (10, 26)],
    4002: [(40, -30), (62, -30), (62, -12), (40, -12)],
}
TRAJ_Z = 0.9


def write_geojson(path, shift_east):
    features = []
    for way_id, corners in BUILDINGS.items():
        ring = [list(reversed(to_lat_lon(e + shift_east, n))) for e, n in corners]
        ring.append(ring[0])
        features.append({"type": "Feature",
                         "geometry": {"type": "Polygon", "coordinates": [ring]},
                         "properties": {"id": way_id, "tags": {"building": "yes"}}})
    with open(path, "w") as f:
        json.dump({"type": "FeatureCollection", "features": features}, f, indent=1)


def synthetic_points():
    """Wall points along the corrected outlines (2..5 m above the trajectory) and ground points:
    a few hundred (x, y, z, intensity)."""
    rng = np.random.default_rng(1)
    rows = []
    for corners in BUILDINGS.values():
        for (x0, y0), (x1, y1) in zip(corners, corners[1:] + corners[:1]):
            for t in np.linspace(0, 1, 25, endpoint=False):
                rows.append([x0 + 1.5 + t * (x1 - x0), y0 + t * (y1 - y0),
                             TRAJ_Z + rng.uniform(2, 5), rng.uniform(0, 1)])
    for x, y in rng.uniform(-10, 70, size=(100, 2)):
        rows.append([x, y, TRAJ_Z - 1.7, 0.2])
    return np.array(rows, dtype=np.float32)


def write_pcd(path, points, data="binary"):
    """PCL-style PCD; the binary one also carries a uint16 'ring' field (mixed sizes)."""
    n = len(points)
    if data == "binary":
        head = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
                "FIELDS x y z intensity ring\nSIZE 4 4 4 4 2\nTYPE F F F F U\nCOUNT 1 1 1 1 1\n"
                "WIDTH %d\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA binary\n" % (n, n))
        body = b"".join(struct.pack("<ffffH", *p, i % 64) for i, p in enumerate(points))
    else:
        head = ("VERSION .7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
                "WIDTH %d\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA ascii\n" % (n, n))
        body = "".join("%.6f %.6f %.6f %.3f\n" % tuple(p) for p in points).encode()
    with open(path, "wb") as f:
        f.write(head.encode() + body)


def write_tum(path, shift_north=0.0):
    with open(path, "w") as f:
        f.write("# time tx ty tz qx qy qz qw\n")
        for i in range(10):
            f.write("%.3f %g %g %g 0 0 0 1\n"
                    % (1317000000 + 0.1 * i, 5.0 * i, 0.5 * i + shift_north, TRAJ_Z))


def make_folder(folder, pcd="binary"):
    os.makedirs(folder, exist_ok=True)
    write_pcd(os.path.join(folder, "map.pcd"), synthetic_points(), pcd)
    write_geojson(os.path.join(folder, "buildings_prior.geojson"), 0.0)
    write_geojson(os.path.join(folder, "buildings_corrected.geojson"), 1.5)
    with open(os.path.join(folder, "origin.txt"), "w") as f:
        f.write("%.12g %.12g %.12g\n" % ORIGIN)
    write_tum(os.path.join(folder, "trajectory_tum.txt"))


def run(*args):
    p = subprocess.run([sys.executable, SCRIPT] + list(args), capture_output=True, text=True,
                       timeout=120)
    return p.returncode, p.stdout, p.stderr


class PlotMapOverlayTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="plot_map_overlay_")
        self.run_dir = os.path.join(self.tmp, "run_osm")
        make_folder(self.run_dir)

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def assertValidPng(self, path):
        self.assertTrue(os.path.isfile(path), path)
        with open(path, "rb") as f:
            head = f.read(24)
        self.assertEqual(head[:8], b"\x89PNG\r\n\x1a\n")
        self.assertEqual(head[12:16], b"IHDR")
        width, height = struct.unpack(">II", head[16:24])
        self.assertTrue(400 <= width <= 4000 and 300 <= height <= 4000, (width, height))
        self.assertGreater(os.path.getsize(path), 10000)

    def test_binary_pcd_folder_with_baseline(self):
        baseline = os.path.join(self.tmp, "run_noosm")
        os.makedirs(baseline)
        write_tum(os.path.join(baseline, "trajectory_tum.txt"), shift_north=2.0)
        out = os.path.join(self.tmp, "overlay.png")
        status, stdout, stderr = run(self.run_dir, "--baseline", baseline, "-o", out)
        self.assertEqual(status, 0, stderr)
        self.assertEqual(stdout.strip(), out)
        self.assertValidPng(out)
        self.assertNotIn("note", stderr)

    def test_ascii_pcd_reads_like_binary_and_default_output(self):
        ascii_dir = os.path.join(self.tmp, "run_ascii")
        make_folder(ascii_dir, pcd="ascii")
        a = pmo.read_pcd(os.path.join(ascii_dir, "map.pcd"))
        b = pmo.read_pcd(os.path.join(self.run_dir, "map.pcd"))
        self.assertEqual(a.shape, (len(synthetic_points()), 3))
        np.testing.assert_allclose(a, b, atol=1e-4)
        np.testing.assert_allclose(b, synthetic_points()[:, :3], atol=1e-6)
        status, _, stderr = run(ascii_dir, "--z-min", "0.5", "--z-max", "8", "--margin", "10")
        self.assertEqual(status, 0, stderr)
        self.assertValidPng(os.path.join(ascii_dir, "map_overlay.png"))

    def test_geojson_outlines_keep_the_way_id(self):
        outlines = pmo.read_geojson_outlines(os.path.join(self.run_dir, "buildings_prior.geojson"))
        self.assertEqual(sorted(i for i, _ in outlines), [4001, 4002])
        ring = pmo.enu(dict(outlines)[4001], ORIGIN)
        np.testing.assert_allclose(ring[:4], BUILDINGS[4001], atol=0.01)

    def test_corrupt_pcd_exits_2_naming_the_file(self):
        path = os.path.join(self.run_dir, "map.pcd")
        with open(path, "rb") as f:
            data = f.read()
        for corrupt in (data[: len(data) // 2],                      # truncated binary data
                        b"this is not a point cloud\n",               # no header
                        data.replace(b"DATA binary", b"DATA binary_compressed")):
            with open(path, "wb") as f:
                f.write(corrupt)
            status, _, stderr = run(self.run_dir, "-o", os.path.join(self.tmp, "x.png"))
            self.assertEqual(status, 2, stderr)
            self.assertIn("map.pcd", stderr)
            self.assertNotIn("Traceback", stderr)
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "x.png")))

    def test_missing_or_corrupt_inputs_exit_2(self):
        status, _, stderr = run(os.path.join(self.tmp, "nowhere"))
        self.assertEqual(status, 2)
        self.assertIn("no such folder", stderr)
        with open(os.path.join(self.run_dir, "buildings_prior.geojson"), "w") as f:
            f.write('{"type": "FeatureCollection", "features": [{"geometry": ')
        status, _, stderr = run(self.run_dir)
        self.assertEqual(status, 2)
        self.assertIn("buildings_prior.geojson", stderr)
        with open(os.path.join(self.run_dir, "trajectory_tum.txt"), "a") as f:
            f.write("1317000001.0 1 2 3\n")
        status, _, stderr = run(self.run_dir)
        self.assertEqual(status, 2)
        self.assertIn("trajectory_tum.txt:12", stderr)
        os.remove(os.path.join(self.run_dir, "map.pcd"))
        write_tum(os.path.join(self.run_dir, "trajectory_tum.txt"))
        status, _, stderr = run(self.run_dir)
        self.assertEqual(status, 2)
        self.assertIn("map.pcd", stderr)

    def test_missing_optional_files_are_noted(self):
        os.remove(os.path.join(self.run_dir, "buildings_corrected.geojson"))
        out = os.path.join(self.tmp, "overlay.png")
        status, _, stderr = run(self.run_dir, "--baseline", os.path.join(self.tmp, "none"),
                                "-o", out)
        self.assertEqual(status, 0, stderr)
        self.assertIn("note: no %s" % os.path.join(self.run_dir, "buildings_corrected.geojson"),
                      stderr)
        self.assertIn("baseline is not drawn", stderr)
        self.assertValidPng(out)

    def test_prior_and_origin_from_dump_or_map_package(self):
        # offline_slam --output DIR --dump DIR/dump: the prior and origin.txt are in DIR/dump
        dump = os.path.join(self.run_dir, "dump")
        os.makedirs(dump)
        for name in ("buildings_prior.geojson", "origin.txt"):
            os.rename(os.path.join(self.run_dir, name), os.path.join(dump, name))
        self.assertEqual(pmo.read_origin(self.run_dir), ORIGIN)
        status, _, stderr = run(self.run_dir, "-o", os.path.join(self.tmp, "a.png"))
        self.assertEqual(status, 0, stderr)
        self.assertNotIn("note", stderr)
        # without a dump: the origin from map_package/map.yaml
        shutil.rmtree(dump)
        os.makedirs(os.path.join(self.run_dir, "map_package"))
        with open(os.path.join(self.run_dir, "map_package", "map.yaml"), "w") as f:
            f.write("format: osm_graph_slam_map\nversion: 1\nhas_origin: true\norigin:\n"
                    "  lat: %.17g\n  lon: %.17g\n  alt: %.17g\nmap_cloud: map.pcd\n" % ORIGIN)
        self.assertEqual(pmo.read_origin(self.run_dir), ORIGIN)
        status, _, stderr = run(self.run_dir, "-o", os.path.join(self.tmp, "b.png"))
        self.assertEqual(status, 0, stderr)
        self.assertIn("buildings_prior.geojson: the prior outlines are not drawn", stderr)
        self.assertValidPng(os.path.join(self.tmp, "b.png"))

    def test_enu_of_a_point_100_m_north_east(self):
        lat, lon = to_lat_lon(100.0, 100.0)
        np.testing.assert_allclose(exact_enu(lat, lon), (100.0, 100.0), atol=1e-6)
        east, north = pmo.enu([(lon, lat)], ORIGIN)[0]
        self.assertLess(abs(east - 100.0), 0.05)
        self.assertLess(abs(north - 100.0), 0.05)
        np.testing.assert_allclose(pmo.enu([(ORIGIN[1], ORIGIN[0])], ORIGIN), [[0, 0]], atol=1e-9)


if __name__ == "__main__":
    unittest.main()

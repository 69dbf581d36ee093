"""Tests of scripts/evaluate_grid.py on a hand-made map_server pair around one square building:
a grid that marks exactly the footprint's boundary occupied scores 100 % right and 0 % false, a
stray obstacle and a free cell inside the footprint are counted as such, and a missing image or a
bad origin gives exit status 2 naming the problem.

    /usr/bin/python3 -m unittest discover -s test/scripts -p '*_test.py'     (from the repo root)
"""
import contextlib
import importlib.util
import io
import json
import math
import os
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
SCRIPT = os.path.join(REPO, "scripts", "evaluate_grid.py")

spec = importlib.util.spec_from_file_location("evaluate_grid", SCRIPT)
eg = importlib.util.module_from_spec(spec)
spec.loader.exec_module(eg)

ORIGIN = (49.011, 8.417, 115.0)
RES = 0.5
SIZE = 40  # cells: 20 m x 20 m, origin at (-10, -10)
BUILDING = [(-2.9, -2.9), (3.1, -2.9), (3.1, 3.1), (-2.9, 3.1)]  # map metres, off the lattice


def lon_lat(east, north):
    """Inverse of the script's ENU at the test's distances (a few metres: sub-millimetre)."""
    to_enu = eg.enu_converter(ORIGIN)
    lon, lat = ORIGIN[1], ORIGIN[0]
    for _ in range(5):  # Newton on a locally linear map
        e, n = to_enu(lon, lat)
        de, dn = to_enu(lon + 1e-5, lat), to_enu(lon, lat + 1e-5)
        lon += (east - e) / ((de[0] - e) / 1e-5)
        lat += (north - n) / ((dn[1] - n) / 1e-5)
    return lon, lat


def cell_centre(i):
    return (-10 + (i % SIZE + 0.5) * RES, -10 + (i // SIZE + 0.5) * RES)


class EvaluateGridTest(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()
        ring = [list(lon_lat(x, y)) for x, y in BUILDING]
        with open(os.path.join(self.dir, "true.geojson"), "w") as f:
            json.dump({"type": "FeatureCollection", "features": [{
                "type": "Feature", "properties": {},
                "geometry": {"type": "Polygon", "coordinates": [ring + [ring[0]]]}}]}, f)
        raster = eg.rasterise([BUILDING], SIZE, SIZE, RES, (-10.0, -10.0))
        # Walls occupied, inside unknown (never seen), everything else free.
        self.cells = [eg.OCCUPIED if raster.wall[i] else eg.UNKNOWN if raster.inside[i] else eg.FREE
                      for i in range(SIZE * SIZE)]
        self.walls = sum(raster.wall)

    def write(self, cells):
        pixel = {eg.OCCUPIED: 0, eg.FREE: 254, eg.UNKNOWN: 205}
        rows = [bytes(pixel[cells[y * SIZE + x]] for x in range(SIZE)) for y in range(SIZE)]
        with open(os.path.join(self.dir, "map.pgm"), "wb") as f:
            f.write(b"P5\n# test\n%d %d\n255\n" % (SIZE, SIZE) + b"".join(reversed(rows)))
        with open(os.path.join(self.dir, "map.yaml"), "w") as f:
            f.write("image: map.pgm\nresolution: %g\norigin: [-10.0, -10.0, 0.0]\nnegate: 0\n"
                    "occupied_thresh: 0.65\nfree_thresh: 0.196\n" % RES)
        return os.path.join(self.dir, "map.yaml")

    def evaluate(self, cells, **kw):
        return eg.evaluate(self.write(cells), os.path.join(self.dir, "true.geojson"),
                           list(ORIGIN), **kw)

    def test_the_footprints_boundary_scores_right(self):
        r = self.evaluate(self.cells)
        self.assertEqual(r["wall_cells_observed"], self.walls)
        self.assertEqual(self.walls, 4 * 12)  # 6 m sides over 13 cells of 0.5 m, corners shared
        self.assertEqual(r["occupied_right"], 1.0)
        self.assertEqual(r["free_marked_occupied"], 0.0)
        self.assertEqual(r["free_inside"], 0)
        self.assertEqual(r["occupied_near_walls"], 1.0)  # the edges run 0.15 m from the wall cells' centres
        self.assertGreater(r["free_cells_observed"], 1000)
        self.assertAlmostEqual(r["wall_length_seen_m"], 24.0, places=6)  # the whole outline
        self.assertAlmostEqual(r["wall_length_occupied"], 1.0)

    def test_stray_obstacles_and_free_cells_inside_are_counted(self):
        cells = list(self.cells)
        stray = next(i for i in range(len(cells)) if cell_centre(i) == (-7.75, -7.75))
        cells[stray] = eg.OCCUPIED
        inside = next(i for i in range(len(cells)) if cell_centre(i) == (0.25, 0.25))
        cells[inside] = eg.FREE
        missed = next(i for i, v in enumerate(cells) if v == eg.OCCUPIED and i != stray)
        cells[missed] = eg.UNKNOWN  # unobserved: neither right nor wrong
        r = self.evaluate(cells)
        self.assertEqual(r["wall_cells_observed"], self.walls - 1)
        self.assertEqual(r["occupied_right"], 1.0)
        self.assertAlmostEqual(r["free_marked_occupied"], 1.0 / r["free_cells_observed"])
        self.assertEqual(r["free_inside"], 1)

    def test_a_wall_the_grid_calls_free_is_not_confirmed(self):
        cells = list(self.cells)
        for i, v in enumerate(cells):  # the east wall (x 3.0-3.5) free instead of occupied
            if v == eg.OCCUPIED and cell_centre(i)[0] > 3.0 and -2.5 < cell_centre(i)[1] < 2.5:
                cells[i] = eg.FREE
        r = self.evaluate(cells)
        self.assertAlmostEqual(r["wall_length_seen_m"], 24.0, places=6)
        self.assertAlmostEqual(r["wall_length_occupied"], 20.0 / 24.0, delta=0.05)

    def test_a_shifted_truth_is_found(self):
        shifted = [(x + 1.0, y + 1.0) for x, y in BUILDING]
        raster = eg.rasterise([shifted], SIZE, SIZE, RES, (-10.0, -10.0))
        cells = [eg.OCCUPIED if raster.wall[i] else eg.UNKNOWN if raster.inside[i] else eg.FREE
                 for i in range(SIZE * SIZE)]
        r = self.evaluate(cells, search_shift=1.5)
        self.assertLess(r["occupied_right"], 0.2)
        self.assertEqual(r["best_shift"]["occupied_right"], 1.0)
        self.assertAlmostEqual(r["best_shift"]["shift"][0], 1.0)
        self.assertAlmostEqual(r["best_shift"]["shift"][1], 1.0)

    def test_bad_inputs_exit_2_naming_the_problem(self):
        yaml_path = self.write(self.cells)
        os.remove(os.path.join(self.dir, "map.pgm"))
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            status = eg.main(["--map", yaml_path, "--buildings",
                              os.path.join(self.dir, "true.geojson"), "--origin", "49,8.4"])
        self.assertEqual(status, 2)
        self.assertIn("map.pgm", err.getvalue())
        with contextlib.redirect_stderr(io.StringIO()):
            self.assertEqual(eg.main(["--map", yaml_path, "--buildings", "x", "--origin", "49"]), 2)


if __name__ == "__main__":
    unittest.main()

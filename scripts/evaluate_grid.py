#!/usr/bin/env python3
"""Compares an occupancy grid saved in map_server's format (save_map's map.yaml + map.pgm) with
the true building footprints (the simulator's buildings_true.geojson) rasterised at the grid's
resolution in the map frame, and prints the numbers of issue 58's targets:

  occupied_right        of the true wall cells (a footprint's boundary runs through them) the
                        grid observed (not unknown), the share it marks occupied
  occupied_right_1cell  the same, a wall cell also counting when an occupied cell touches it
  free_marked_occupied  of the observed cells outside every footprint and not touching a wall
                        cell, the share marked occupied (cars, trees, fences and people of the
                        simulated city count here: the footprints do not hold them)
  free_inside           observed cells inside a footprint (centre inside, not a wall cell)
                        marked free: should be 0
  occupied_near_walls   of the occupied cells, the share whose centre lies within --wall-tolerance
                        of a footprint edge
  wall_length_seen_m    footprint edge length (sampled every 5 cm) with an observed cell centre
                        within --wall-tolerance: the walls the drive saw
  wall_length_occupied  of that length, the share with an occupied cell centre within
                        --wall-tolerance (the real drive's target: >= 80 % against the corrected
                        OSM walls, 0.3 m)

The map frame is offline_slam's: ENU at --origin (the drive's first GNSS fix), so the grid's own
absolute error (the SLAM's) is part of the numbers; --search-shift M also reports the best
translation of the truth within +-M (a global offset, not the local errors).

    scripts/evaluate_grid.py --map OUT/map.yaml --buildings SIM/buildings_true.geojson \\
        --origin LAT,LON[,ALT] [--search-shift 1.0] [--json]

Standard library only. Exit status 2 with a message for unreadable inputs.
"""
import argparse
import json
import math
import os
import sys

OCCUPIED, FREE, UNKNOWN = 100, 0, -1
WGS84_A, WGS84_F = 6378137.0, 1.0 / 298.257223563


class InputError(Exception):
    pass


def read_map_yaml(path):
    """The keys of map_server's YAML this script needs (flat 'key: value' lines)."""
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise InputError("%s: %s" % (path, e.strerror))
    values = {}
    for line in lines:
        line = line.split("#", 1)[0]
        if ":" in line:
            key, value = line.split(":", 1)
            values[key.strip()] = value.strip()
    try:
        origin = [float(v) for v in values["origin"].strip("[]").split(",")]
        meta = {"image": values["image"], "resolution": float(values["resolution"]),
                "origin": origin, "occupied_thresh": float(values["occupied_thresh"]),
                "free_thresh": float(values["free_thresh"]), "negate": int(values["negate"])}
    except (KeyError, ValueError, IndexError) as e:
        raise InputError("%s: not a map_server map (%s)" % (path, e))
    if not meta["image"].startswith("/"):
        meta["image"] = os.path.join(os.path.dirname(path), meta["image"])
    return meta


def pgm_tokens(data, count):
    """The first `count` header fields of a PGM and the offset after them (comments skipped)."""
    tokens, i = [], 0
    while len(tokens) < count:
        while i < len(data) and (data[i:i + 1].isspace() or data[i:i + 1] == b"#"):
            if data[i:i + 1] == b"#":
                i = data.index(b"\n", i)
            i += 1
        j = i
        while j < len(data) and not data[j:j + 1].isspace():
            j += 1
        tokens.append(data[i:j].decode("ascii"))
        i = j
    return tokens, i + 1  # one whitespace byte before the raster


def read_grid(yaml_path):
    """(meta, width, height, cells): cells row-major with row 0 at the lowest y, in map_server's
    trinary reading (100 occupied, 0 free, -1 unknown)."""
    meta = read_map_yaml(yaml_path)
    try:
        with open(meta["image"], "rb") as f:
            data = f.read()
    except OSError as e:
        raise InputError("%s: %s" % (meta["image"], e.strerror))
    try:
        (magic, w, h, maxval), start = pgm_tokens(data, 4)
        width, height = int(w), int(h)
    except (ValueError, IndexError):
        raise InputError("%s: not a PGM" % meta["image"])
    if magic != "P5" or maxval != "255" or len(data) < start + width * height:
        raise InputError("%s: not an 8-bit binary PGM of %sx%s" % (meta["image"], w, h))
    raster = data[start:start + width * height]
    lookup = []
    for value in range(256):
        p = value / 255.0 if meta["negate"] else (255 - value) / 255.0
        lookup.append(OCCUPIED if p > meta["occupied_thresh"] else
                      FREE if p < meta["free_thresh"] else UNKNOWN)
    cells = [UNKNOWN] * (width * height)
    for row in range(height):
        y = height - 1 - row  # image row 0 is the top (the highest y)
        line = raster[row * width:(row + 1) * width]
        cells[y * width:(y + 1) * width] = [lookup[v] for v in line]
    return meta, width, height, cells


def ecef(lat, lon, h):
    e2 = WGS84_F * (2 - WGS84_F)
    la, lo = math.radians(lat), math.radians(lon)
    n = WGS84_A / math.sqrt(1 - e2 * math.sin(la) ** 2)
    return ((n + h) * math.cos(la) * math.cos(lo), (n + h) * math.cos(la) * math.sin(lo),
            (n * (1 - e2) + h) * math.sin(la))


def enu_converter(origin):
    """lon, lat -> (east, north) at the origin's height, through ECEF (as LocalCartesian)."""
    lat0, lon0, h0 = origin
    x0, y0, z0 = ecef(lat0, lon0, h0)
    sla, cla = math.sin(math.radians(lat0)), math.cos(math.radians(lat0))
    slo, clo = math.sin(math.radians(lon0)), math.cos(math.radians(lon0))

    def convert(lon, lat):
        x, y, z = ecef(lat, lon, h0)
        dx, dy, dz = x - x0, y - y0, z - z0
        return (-slo * dx + clo * dy, -sla * clo * dx - sla * slo * dy + cla * dz)
    return convert


def read_footprints(path, origin):
    """Outer rings of the GeoJSON's polygons in map-frame metres."""
    try:
        with open(path) as f:
            features = json.load(f)["features"]
    except (OSError, ValueError, KeyError) as e:
        raise InputError("%s: %s" % (path, e))
    to_enu = enu_converter(origin)
    rings = []
    for feature in features:
        geometry = feature.get("geometry") or {}
        polygons = ([geometry["coordinates"]] if geometry.get("type") == "Polygon" else
                    geometry.get("coordinates", []) if geometry.get("type") == "MultiPolygon" else [])
        for polygon in polygons:
            if polygon and len(polygon[0]) >= 3:
                rings.append([to_enu(p[0], p[1]) for p in polygon[0]])
    return rings


class Raster:
    """Cell classes of the truth on the grid's lattice: wall cells and interior cells."""

    def __init__(self, width, height, resolution, origin):
        self.width, self.height, self.res = width, height, resolution
        self.ox, self.oy = origin
        self.wall = bytearray(width * height)
        self.inside = bytearray(width * height)

    def index(self, x, y):
        cx, cy = int(math.floor((x - self.ox) / self.res)), int(math.floor((y - self.oy) / self.res))
        if 0 <= cx < self.width and 0 <= cy < self.height:
            return cy * self.width + cx
        return None

    def add_edge(self, a, b):
        steps = max(1, int(math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / (self.res / 8))))
        for k in range(steps + 1):
            i = self.index(a[0] + (b[0] - a[0]) * k / steps, a[1] + (b[1] - a[1]) * k / steps)
            if i is not None:
                self.wall[i] = 1

    def fill(self, ring):
        ys = [p[1] for p in ring]
        row0 = max(0, int(math.floor((min(ys) - self.oy) / self.res)))
        row1 = min(self.height - 1, int(math.floor((max(ys) - self.oy) / self.res)))
        edges = list(zip(ring, ring[1:] + ring[:1]))
        for row in range(row0, row1 + 1):
            yc = self.oy + (row + 0.5) * self.res
            xs = sorted(a[0] + (yc - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
                        for a, b in edges if (a[1] <= yc) != (b[1] <= yc))
            for x0, x1 in zip(xs[0::2], xs[1::2]):  # centres between two crossings are inside
                c0 = max(0, int(math.ceil((x0 - self.ox) / self.res - 0.5)))
                c1 = min(self.width - 1, int(math.floor((x1 - self.ox) / self.res - 0.5)))
                if c1 >= c0:
                    self.inside[row * self.width + c0:row * self.width + c1 + 1] = b"\x01" * (c1 - c0 + 1)


def rasterise(rings, width, height, resolution, origin):
    raster = Raster(width, height, resolution, origin)
    for ring in rings:
        for a, b in zip(ring, ring[1:] + ring[:1]):
            raster.add_edge(a, b)
        raster.fill(ring)
    return raster


def neighbours(i, width, height):
    x, y = i % width, i // width
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if (dx or dy) and 0 <= x + dx < width and 0 <= y + dy < height:
                yield (y + dy) * width + x + dx


def segment_distance(p, a, b):
    ax, ay = b[0] - a[0], b[1] - a[1]
    length2 = ax * ax + ay * ay
    t = 0.0 if length2 == 0 else max(0.0, min(1.0, ((p[0] - a[0]) * ax + (p[1] - a[1]) * ay) / length2))
    return math.hypot(p[0] - a[0] - t * ax, p[1] - a[1] - t * ay)


def share_near_walls(cells, width, meta, rings, tolerance):
    """Of the occupied cells, the share with the centre within tolerance of a footprint edge."""
    bucket = 5.0
    index = {}
    for ring in rings:
        for a, b in zip(ring, ring[1:] + ring[:1]):
            for bx in range(int(math.floor((min(a[0], b[0]) - tolerance) / bucket)),
                            int(math.floor((max(a[0], b[0]) + tolerance) / bucket)) + 1):
                for by in range(int(math.floor((min(a[1], b[1]) - tolerance) / bucket)),
                                int(math.floor((max(a[1], b[1]) + tolerance) / bucket)) + 1):
                    index.setdefault((bx, by), []).append((a, b))
    res, (ox, oy) = meta["resolution"], meta["origin"][:2]
    occupied = near = 0
    for i, v in enumerate(cells):
        if v != OCCUPIED:
            continue
        occupied += 1
        p = (ox + (i % width + 0.5) * res, oy + (i // width + 0.5) * res)
        segments = index.get((int(math.floor(p[0] / bucket)), int(math.floor(p[1] / bucket))), ())
        near += any(segment_distance(p, a, b) <= tolerance for a, b in segments)
    return near / occupied if occupied else float("nan"), occupied


def wall_length_metrics(cells, width, height, meta, rings, tolerance, step=0.05):
    res, (ox, oy) = meta["resolution"], meta["origin"][:2]
    reach = int(math.ceil(tolerance / res)) + 1
    seen = occupied = 0.0
    for ring in rings:
        for a, b in zip(ring, ring[1:] + ring[:1]):
            length = math.hypot(b[0] - a[0], b[1] - a[1])
            n = max(1, int(math.ceil(length / step)))
            for k in range(n):
                t = (k + 0.5) / n
                px, py = a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])
                cx, cy = int(math.floor((px - ox) / res)), int(math.floor((py - oy) / res))
                near_seen = near_occupied = False
                for y in range(max(0, cy - reach), min(height, cy + reach + 1)):
                    for x in range(max(0, cx - reach), min(width, cx + reach + 1)):
                        v = cells[y * width + x]
                        if v == UNKNOWN or math.hypot(ox + (x + 0.5) * res - px,
                                                      oy + (y + 0.5) * res - py) > tolerance:
                            continue
                        near_seen = True
                        near_occupied = near_occupied or v == OCCUPIED
                seen += near_seen * length / n
                occupied += near_occupied * length / n
    return {"wall_length_seen_m": seen,
            "wall_length_occupied": occupied / seen if seen else float("nan")}


def grid_metrics(cells, width, height, raster):
    wall_seen = wall_occupied = wall_occupied_1cell = 0
    free_seen = free_occupied = inside_free = inside_seen = 0
    for i, v in enumerate(cells):
        if v == UNKNOWN:
            continue
        if raster.wall[i]:
            wall_seen += 1
            wall_occupied += v == OCCUPIED
            wall_occupied_1cell += v == OCCUPIED or any(
                cells[j] == OCCUPIED for j in neighbours(i, width, height))
        elif raster.inside[i]:
            inside_seen += 1
            inside_free += v == FREE
        elif not any(raster.wall[j] for j in neighbours(i, width, height)):
            free_seen += 1
            free_occupied += v == OCCUPIED
    ratio = lambda a, b: a / b if b else float("nan")
    return {"wall_cells_observed": wall_seen,
            "occupied_right": ratio(wall_occupied, wall_seen),
            "occupied_right_1cell": ratio(wall_occupied_1cell, wall_seen),
            "free_cells_observed": free_seen,
            "free_marked_occupied": ratio(free_occupied, free_seen),
            "inside_cells_observed": inside_seen,
            "free_inside": inside_free}


def evaluate(yaml_path, buildings_path, origin, wall_tolerance=0.3, search_shift=0.0):
    meta, width, height, cells = read_grid(yaml_path)
    rings = read_footprints(buildings_path, origin)
    grid_origin = tuple(meta["origin"][:2])
    result = {"width": width, "height": height, "resolution": meta["resolution"],
              "buildings": len(rings)}
    result.update(grid_metrics(cells, width, height,
                               rasterise(rings, width, height, meta["resolution"], grid_origin)))
    result["occupied_near_walls"], result["occupied_cells"] = share_near_walls(
        cells, width, meta, rings, wall_tolerance)
    result.update(wall_length_metrics(cells, width, height, meta, rings, wall_tolerance))
    if search_shift > 0:
        result["best_shift"] = best_shift(cells, width, height, meta, rings, search_shift)
    return result


def best_shift(cells, width, height, meta, rings, limit):
    """The translation of the truth (coarse 2-cell steps, then 1) with the most wall cells right."""
    res = meta["resolution"]
    best = None
    for step in (2 * res, res):
        centre = (0.0, 0.0) if best is None else best["shift"]
        span = int(round(limit / step)) if best is None else 2
        for i in range(-span, span + 1):
            for j in range(-span, span + 1):
                shift = (centre[0] + i * step, centre[1] + j * step)
                moved = [[(x + shift[0], y + shift[1]) for x, y in ring] for ring in rings]
                m = grid_metrics(cells, width, height, rasterise(
                    moved, width, height, res, tuple(meta["origin"][:2])))
                if best is None or m["occupied_right"] > best["occupied_right"]:
                    best = dict(m, shift=shift)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--map", required=True, help="map.yaml (map_server format)")
    ap.add_argument("--buildings", required=True, help="true footprints (GeoJSON)")
    ap.add_argument("--origin", required=True, help="LAT,LON[,ALT] of the map frame")
    ap.add_argument("--wall-tolerance", type=float, default=0.3, help="[m] (default: 0.3)")
    ap.add_argument("--search-shift", type=float, default=0.0,
                    help="[m] also the best translation of the truth within this (slow)")
    ap.add_argument("--json", action="store_true", help="one JSON object instead of text")
    args = ap.parse_args(argv)
    try:
        origin = [float(v) for v in args.origin.split(",")]
        if len(origin) not in (2, 3):
            raise ValueError
    except ValueError:
        print("evaluate_grid: --origin must be LAT,LON[,ALT]", file=sys.stderr)
        return 2
    if len(origin) == 2:
        origin.append(0.0)
    try:
        result = evaluate(args.map, args.buildings, origin, args.wall_tolerance, args.search_shift)
    except InputError as e:
        print("evaluate_grid: %s" % e, file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(result, indent=1, sort_keys=True))
    else:
        for key in sorted(result):
            print("%-24s %s" % (key, result[key]))
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Bird's-eye PNG of a SLAM output folder: the accumulated map (wall band), the OSM prior
outlines, the corrected outlines and the trajectory, in ENU metres around the map origin.

  plot_map_overlay.py DIR [--baseline DIR2] [-o FILE] [--z-min 1.0] [--z-max 6.0]
                      [--margin 40] [--max-points 200000] [--prior FILE.geojson|FILE.osm]

DIR is what `offline_slam --output DIR` or the `save_map` service writes (src/slam/map_export.cpp):
  map.pcd                      the map cloud (PCD, ascii or binary; x y z used), map frame = ENU
  trajectory_tum.txt           stamp x y z qx qy qz qw, map frame
  buildings_corrected.geojson  the corrected outlines (lon/lat); optional
  buildings_prior.geojson      the OSM prior the run used, written by offline_slam and by
                               dump_graph (`offline_slam --dump`): looked for in DIR and DIR/dump;
                               optional, or give it with --prior (GeoJSON or the .osm extract)
  origin.txt                   "lat lon alt" of the ENU origin (dump_graph; DIR or DIR/dump), else
                               the origin in DIR/map_package/map.yaml; needed to draw outlines
--baseline DIR2 adds DIR2/trajectory_tum.txt (e.g. the same drive with --no-osm). Map points are
drawn when their z lies in [z-min, z-max] above the trajectory's mean z, so that walls show and
the ground does not. Writes DIR/map_overlay.png unless -o is given. Exit status 2 on a missing
folder or a missing/corrupt input file; missing optional files are skipped with a note.
"""
import argparse
import json
import math
import os
import re
import sys
import xml.etree.ElementTree as ET

import numpy as np

PROG = "plot_map_overlay"


class InputError(Exception):
    """A missing or unreadable input file: reported on stderr, exit status 2."""


def note(message):
    sys.stderr.write("%s: note: %s\n" % (PROG, message))


def read_pcd(path):
    """(N, 3) float array of the finite x, y, z of a PCD file (DATA ascii or binary)."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise InputError("cannot read %s: %s" % (path, e.strerror))
    header, pos = {}, 0
    while True:
        end = raw.find(b"\n", pos)
        if end < 0:
            raise InputError("%s: not a PCD file (no DATA line in the header)" % path)
        line = raw[pos:end].decode("ascii", "replace").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, _, value = line.partition(" ")
        header[key.upper()] = value.split()
        if key.upper() == "DATA":
            break
    try:
        fields = header["FIELDS"]
        sizes = [int(s) for s in header["SIZE"]]
        types = header["TYPE"]
        counts = [int(c) for c in header.get("COUNT", ["1"] * len(fields))]
        points = int(header["POINTS"][0]) if "POINTS" in header else \
            int(header["WIDTH"][0]) * int(header.get("HEIGHT", ["1"])[0])
        data = header["DATA"][0].lower()
    except (KeyError, IndexError, ValueError) as e:
        raise InputError("%s: not a valid PCD header (%s)" % (path, e))
    if not (len(fields) == len(sizes) == len(types) == len(counts)) or \
            not {"x", "y", "z"} <= set(fields):
        raise InputError("%s: PCD header needs matching FIELDS/SIZE/TYPE/COUNT with x, y, z" % path)
    if data == "binary_compressed":
        raise InputError("%s: DATA binary_compressed is not supported; convert it with "
                         "`pcl_convert_pcd_ascii_binary %s out.pcd 1`" % (path, path))
    if data == "binary":
        kinds = {"F": "f", "I": "i", "U": "u"}
        try:
            dtype = np.dtype([(f if f != "_" else "_pad%d" % i,
                               "<%s%d" % (kinds[t.upper()], s), (c,) if c > 1 else ())
                              for i, (f, s, t, c) in enumerate(zip(fields, sizes, types, counts))])
        except (KeyError, TypeError) as e:
            raise InputError("%s: unsupported PCD field type (%s)" % (path, e))
        if len(raw) - pos < points * dtype.itemsize:
            raise InputError("%s: truncated: %d points of %d bytes announced, %d bytes of data"
                             % (path, points, dtype.itemsize, len(raw) - pos))
        rec = np.frombuffer(raw, dtype=dtype, count=points, offset=pos)
        xyz = np.column_stack([rec["x"], rec["y"], rec["z"]]).astype(np.float64)
    elif data == "ascii":
        columns = np.cumsum([0] + counts)  # first column of each field
        try:
            lines = raw[pos:].decode("ascii").splitlines()
            rows = np.loadtxt(lines, ndmin=2) if any(l.strip() for l in lines) else \
                np.zeros((0, columns[-1]))
        except (ValueError, UnicodeDecodeError) as e:
            raise InputError("%s: corrupt ascii PCD data (%s)" % (path, e))
        if rows.shape != (points, columns[-1]):
            raise InputError("%s: %d rows of %d numbers, the header announces %d of %d"
                             % (path, rows.shape[0], rows.shape[1], points, columns[-1]))
        xyz = rows[:, [columns[fields.index(a)] for a in "xyz"]]
    else:
        raise InputError("%s: unknown PCD DATA type '%s'" % (path, data))
    return xyz[np.isfinite(xyz).all(axis=1)]


def read_geojson_outlines(path):
    """[(id, (K, 2) lon/lat array)] of the outer rings of the Polygon features of a GeoJSON file."""
    try:
        with open(path) as f:
            doc = json.load(f)
        outlines = []
        for feature in doc["features"]:
            geometry = feature["geometry"]
            polygons = geometry["coordinates"] if geometry["type"] == "MultiPolygon" else \
                [geometry["coordinates"]] if geometry["type"] == "Polygon" else []
            props = feature.get("properties") or {}
            for polygon in polygons:
                ring = np.array(polygon[0], dtype=float)[:, :2]
                outlines.append((props.get("id", props.get("osm_id")), ring))
        return outlines
    except OSError as e:
        raise InputError("cannot read %s: %s" % (path, e.strerror))
    except (ValueError, KeyError, TypeError, IndexError) as e:
        raise InputError("%s: corrupt GeoJSON (%s: %s)" % (path, type(e).__name__, e))


def read_osm_outlines(path):
    """[(way id, lon/lat ring)] of the closed ways tagged building=* of an .osm XML extract
    (multipolygon relations are left out: the plot only needs a reference)."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as e:
        raise InputError("cannot read %s: %s" % (path, e))
    nodes = {n.get("id"): (float(n.get("lon")), float(n.get("lat"))) for n in root.iter("node")}
    outlines = []
    for way in root.iter("way"):
        if any(t.get("k") == "building" for t in way.iter("tag")):
            ring = [nodes[nd.get("ref")] for nd in way.iter("nd") if nd.get("ref") in nodes]
            if len(ring) >= 3:
                outlines.append((int(way.get("id")), np.array(ring)))
    return outlines


def find(folder, name):
    """folder/name, else folder/dump/name (offline_slam --output DIR --dump DIR/dump); or None."""
    for path in (os.path.join(folder, name), os.path.join(folder, "dump", name)):
        if os.path.exists(path):
            return path
    return None


def read_origin(folder):
    """(lat, lon, alt) of the ENU origin: origin.txt (in folder or folder/dump), else
    map_package/map.yaml; None if none of them is there."""
    path = find(folder, "origin.txt")
    if path:
        try:
            with open(path) as f:
                values = [float(v) for v in f.read().split()]
            if len(values) < 2 or not all(map(math.isfinite, values)):
                raise ValueError("expected 'lat lon alt'")
            return (values[0], values[1], values[2] if len(values) > 2 else 0.0)
        except (OSError, ValueError) as e:
            raise InputError("%s: corrupt origin (%s)" % (path, e))
    path = os.path.join(folder, "map_package", "map.yaml")
    if os.path.exists(path):
        with open(path) as f:
            text = f.read()
        if re.search(r"^has_origin:\s*false", text, re.M):
            return None
        block = text.split("\norigin:", 1)[-1]
        found = [re.search(r"^\s+%s:\s*(\S+)" % k, block, re.M) for k in ("lat", "lon", "alt")]
        try:
            if not (found[0] and found[1]):
                raise ValueError("no origin lat/lon")
            return tuple(float(m.group(1)) if m else 0.0 for m in found)
        except ValueError as e:
            raise InputError("%s: corrupt origin (%s)" % (path, e))
    return None


def enu(lon_lat, origin):
    """East/north metres of (K, 2) lon/lat points around origin (lat, lon, ...).

    A local tangent-plane approximation with the WGS84 radii of curvature at the origin (the
    project itself uses GeographicLib's LocalCartesian); the error grows as d^2/R: well below
    a millimetre at 100 m, ~0.1 m at 1 km, enough for a plot.
    """
    a, f = 6378137.0, 1.0 / 298.257223563
    e2 = f * (2.0 - f)
    lat0 = math.radians(origin[0])
    w = 1.0 - e2 * math.sin(lat0) ** 2
    n = a / math.sqrt(w)                 # prime vertical radius of curvature
    m = a * (1.0 - e2) / w ** 1.5        # meridian radius of curvature
    ll = np.atleast_2d(np.asarray(lon_lat, dtype=float))
    east = np.radians(ll[:, 0] - origin[1]) * n * math.cos(lat0)
    north = np.radians(ll[:, 1] - origin[0]) * m
    return np.column_stack([east, north])


def read_tum(path):
    """(N, 3) array of the positions of a TUM trajectory (stamp x y z qx qy qz qw)."""
    rows = []
    try:
        with open(path) as f:
            for number, line in enumerate(f, 1):
                if not line.strip() or line.lstrip().startswith("#"):
                    continue
                values = line.split()
                try:
                    if len(values) != 8:
                        raise ValueError("%d numbers" % len(values))
                    rows.append([float(v) for v in values[1:4]])
                except ValueError as e:
                    raise InputError("%s:%d: expected 8 numbers (stamp x y z qx qy qz qw): %s"
                                     % (path, number, e))
    except OSError as e:
        raise InputError("cannot read %s: %s" % (path, e.strerror))
    if not rows:
        raise InputError("%s: no poses" % path)
    return np.array(rows)


def plot(out, title, cloud, trajectory, prior=(), corrected=(), baseline=None,
         label="this run", baseline_label="baseline", z_band=(1.0, 6.0), margin=40.0,
         max_points=200000):
    """Writes the overlay PNG. Outlines: lists of (K, 2) ENU arrays; cloud, trajectories: (N, 3)."""
    import matplotlib
    matplotlib.use("Agg")  # headless
    import matplotlib.pyplot as plt

    extent = trajectory if baseline is None else np.vstack([trajectory, baseline])
    lo = extent[:, :2].min(axis=0) - margin
    hi = extent[:, :2].max(axis=0) + margin
    z0 = trajectory[:, 2].mean()
    keep = ((cloud[:, 2] >= z0 + z_band[0]) & (cloud[:, 2] <= z0 + z_band[1]) &
            (cloud[:, :2] >= lo).all(axis=1) & (cloud[:, :2] <= hi).all(axis=1))
    pts = cloud[keep]
    if len(pts) > max_points:
        pts = pts[np.random.default_rng(0).choice(len(pts), max_points, replace=False)]

    span = hi - lo
    fig, ax = plt.subplots(figsize=(11, max(5.0, min(16.0, 11 * span[1] / span[0]))))
    dot = min(6.0, max(0.5, 30000.0 / max(len(pts), 1)))  # sparse maps get bigger dots
    ax.scatter(pts[:, 0], pts[:, 1], s=dot, c="0.4", marker="o", linewidths=0, rasterized=True)
    ax.plot([], [], "o", color="0.4", ms=4,  # legend entry with a legible marker
            label="map points %.0f..%.0f m above mean trajectory z (%d)"
            % (z_band[0], z_band[1], len(pts)))
    for outlines, style in ((prior, dict(color="tab:red", ls="--", lw=1.4,
                                         label="OSM prior (%d)" % len(prior))),
                            (corrected, dict(color="tab:blue", ls="-", lw=1.6,
                                             label="corrected (%d)" % len(corrected)))):
        for ring in outlines:
            closed = np.vstack([ring, ring[:1]])
            ax.plot(closed[:, 0], closed[:, 1], **style)
            style.pop("label", None)
    ax.plot(trajectory[:, 0], trajectory[:, 1], "-", color="tab:green", lw=3,
            label="trajectory, " + label)
    if baseline is not None:  # dashed on top: both stay visible where they coincide
        ax.plot(baseline[:, 0], baseline[:, 1], "--", color="tab:orange", lw=1.6,
                label="trajectory, " + baseline_label)
    ax.plot(trajectory[0, 0], trajectory[0, 1], "o", ms=9, mfc="tab:green", mec="k",
            label="start", zorder=5)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.grid(True, alpha=0.25)
    ax.legend(loc="best", fontsize=9, framealpha=0.85)
    ax.set_title(title)
    fig.savefig(out, dpi=150, bbox_inches="tight")
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", help="output folder of offline_slam --output / save_map")
    parser.add_argument("--baseline", help="a second run's folder (e.g. --no-osm)")
    parser.add_argument("-o", "--output", help="PNG to write (default FOLDER/map_overlay.png)")
    parser.add_argument("--prior", help="OSM prior outlines (.geojson or .osm) if the folder "
                                        "has no buildings_prior.geojson")
    parser.add_argument("--z-min", type=float, default=1.0, help="m above the mean trajectory z")
    parser.add_argument("--z-max", type=float, default=6.0, help="m above the mean trajectory z")
    parser.add_argument("--margin", type=float, default=40.0, help="m around the trajectories")
    parser.add_argument("--max-points", type=int, default=200000)
    args = parser.parse_args(argv)
    try:
        folder = args.folder.rstrip("/") or "/"
        if not os.path.isdir(folder):
            raise InputError("no such folder: %s" % folder)
        trajectory = read_tum(os.path.join(folder, "trajectory_tum.txt"))
        cloud = read_pcd(os.path.join(folder, "map.pcd"))

        prior_path = args.prior or find(folder, "buildings_prior.geojson") or \
            os.path.join(folder, "buildings_prior.geojson")
        corrected_path = os.path.join(folder, "buildings_corrected.geojson")
        sets = {}
        for name, path in (("prior", prior_path), ("corrected", corrected_path)):
            if args.prior and name == "prior" and not os.path.exists(path):
                raise InputError("no such file: %s" % path)
            if not os.path.exists(path):
                note("no %s: the %s outlines are not drawn" % (path, name))
                continue
            reader = read_osm_outlines if path.endswith((".osm", ".xml")) else read_geojson_outlines
            sets[name] = reader(path)
        origin = read_origin(folder)
        if sets and origin is None:
            note("no origin.txt or map_package/map.yaml origin in %s: outlines not drawn" % folder)
            sets = {}
        outlines = {k: [enu(ring, origin) for _, ring in v] for k, v in sets.items()}

        baseline, baseline_label = None, ""
        if args.baseline:
            path = os.path.join(args.baseline, "trajectory_tum.txt")
            if os.path.exists(path):
                baseline = read_tum(path)
                baseline_label = os.path.basename(args.baseline.rstrip("/"))
            else:
                note("no %s: the baseline is not drawn" % path)
    except InputError as e:
        sys.stderr.write("%s: %s\n" % (PROG, e))
        return 2

    name = os.path.basename(os.path.abspath(folder))
    title = "%s: map, OSM prior, corrected outlines, trajectory" % name
    if baseline is not None:
        title += "\n(baseline: %s)" % baseline_label
    out = args.output or os.path.join(folder, "map_overlay.png")
    try:
        plot(out, title, cloud, trajectory, outlines.get("prior", []),
             outlines.get("corrected", []), baseline, name, baseline_label,
             (args.z_min, args.z_max), args.margin, args.max_points)
    except OSError as e:
        sys.stderr.write("%s: cannot write %s: %s\n" % (PROG, out, e.strerror or e))
        return 2
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/python3
"""The drive matrix: every accuracy number over many simulated drives instead of one.

For each drive (a world, seed, length, prior model, sensor, GNSS mode, manoeuvres and dropped
scans) it runs

    simulate_urban -> offline_slam (with the OSM prior) -> offline_slam --no-osm (odometry + loops)
    -> evaluate_slam --json

in a folder of its own named by the drive's parameters, collects one row per drive, prints a
fixed-width table with the median and worst of each column, and writes matrix.json. Finished
drives (result.json) are not run again. doc/matrix.md describes presets, axes and columns.

    scripts/slam_matrix.py --preset quick
    scripts/slam_matrix.py --preset default --jobs 2
    scripts/slam_matrix.py --preset default --check --max-ate-ratio 1.0 --min-coverage 0.95
    scripts/slam_matrix.py --world city --seed 1,2 --length 300 --prior-model global --list

Python 3 standard library only.
"""
import argparse
import calendar
import concurrent.futures
import itertools
import json
import math
import os
import re
import shlex
import shutil
import signal
import statistics
import subprocess
import sys
import threading
import time
import traceback

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KARLSRUHE = "../shared/data/osm/2011_09_26_drive_0005_sync.osm"  # relative to the repo

# simulate_urban's axes. A value equal to SIM_DEFAULTS is passed by omitting its flag, so a drive
# with default values runs on a simulator that does not know the flag yet.
PRIOR_MODELS = ("independent", "blocks", "global", "mixed")
SENSORS = ("hdl64e", "os1_64")
GNSS_MODES = ("noisy", "rtk")
SIM_DEFAULTS = {
    "prior_model": "independent",
    "sensor": "hdl64e",
    "gnss": "noisy",
    "manoeuvres": "none",
    "drop_scans": 0.0,
    "dropout_burst": 0,  # N or "N@T": one burst of N consecutive missing scans (at T s)
    "map_shift": 0.0,  # [m] the 'global' prior model's common shift, fixed (0: uniform in 1-3 m)
}
DEFAULT_SIM_ARGS = "--motion-distortion --kitti-calibration-error"  # as scripts/demo.sh
BASELINE_LABEL = "odom+loops"
TOOLS = ("simulate_urban", "offline_slam", "evaluate_slam")

# Time estimate of one drive (both cores for each tool): scans per requested metre and the fewest
# scans of a route (the routes slow down in turns and end at a junction; simulate_urban seeds 1-3:
# Karlsruhe 200 m -> 470-540 scans, 300 m -> 650-920, 1500 m -> 3420-3630; city 200/300 m ->
# 460-700, 1500 m -> 2040-2160), simulate_urban and offline_slam scans per second.
SCANS_PER_M = {"karlsruhe": 2.35, "city": 1.4}
MIN_SCANS = {"karlsruhe": 500, "city": 560}
SCANS_PER_M_OTHER, MIN_SCANS_OTHER = 2.0, 500
MANOEUVRES_ALL_S = 230.0  # drive time [s] manoeuvres 'all' add (city 52 -> 276 s, Karlsruhe 65 -> 286 s)
MANOEUVRE_S = 50.0  # ... and each single manoeuvre (measured 13-85 s)
SIM_SCANS_PER_S = 10.0
SLAM_SCANS_PER_S = 19.0
DRIVE_OVERHEAD_S = 8.0

PRESETS = {
    # 2 worlds x 3 seeds x {300 m: 3 drives, 1500 m: 1 drive} = 24 drives. The (prior model,
    # sensor) pairs rotate so that each appears with both worlds and both lengths.
    "default": {
        "worlds": ["karlsruhe", "city"],
        "seeds": [1, 2, 3],
        "lengths": [300, 1500],
        "prior_models": list(PRIOR_MODELS),
        "sensors": list(SENSORS),
        "gnss": ["noisy"],
        "manoeuvres": ["none"],
        "drop_scans": [0.0],
        "dropout_burst": [0],
        "map_shifts": [0.0],
        "design": "rotation",
        "per_cell_short": 3,
        "per_cell_long": 1,
        # + per world 2 drives whose map is shifted by 1.5 m as a whole: seed 1's first fix is
        # good (0.7 m off), so a map that pulls the trajectory shows as a loss (doc/matrix.md).
        "extra_drives": [{"seed": s, "length": 300, "prior_model": "global", "map_shift": 1.5}
                         for s in (1, 4)],
    },
    # 2 worlds x 2 (prior model, sensor) pairs, 200 m: 4 drives, about 6 minutes.
    "quick": {
        "worlds": ["karlsruhe", "city"],
        "seeds": [1],
        "lengths": [200],
        "prior_models": ["independent", "global"],
        "sensors": list(SENSORS),
        "gnss": ["noisy"],
        "manoeuvres": ["none"],
        "drop_scans": [0.0],
        "dropout_burst": [0],
        "map_shifts": [0.0],
        "design": "rotation",
        "per_cell_short": 2,
        "per_cell_long": 2,
    },
    # The front-end under manoeuvres and missing scans: per world the plain drive (the control),
    # each stressor alone, and all of them together; 300 m requested (manoeuvres 'all' make the
    # route 1.0-1.6 km): 10 drives.
    "stress": {
        "worlds": ["karlsruhe", "city"],
        "seeds": [1],
        "lengths": [300],
        "prior_models": ["independent"],
        "sensors": ["hdl64e"],
        "gnss": ["noisy"],
        "manoeuvres": ["none"],
        "drop_scans": [0.0],
        "dropout_burst": [0],
        "map_shifts": [0.0],
        "design": "product",
        "scenarios": [
            {},
            {"drop_scans": 0.05},
            {"dropout_burst": 20},
            {"manoeuvres": "all"},
            {"manoeuvres": "all", "drop_scans": 0.05, "dropout_burst": 20},
        ],
    },
}
LONG_DRIVE_M = 1000  # rotation design: drives of at least this length get per_cell_long pairs
AXES = ("worlds", "seeds", "lengths", "prior_models", "sensors", "gnss", "manoeuvres",
        "drop_scans", "dropout_burst", "map_shifts")
ROTATED = ("prior_models", "sensors")  # the rotation design's rotated axes


class MatrixError(Exception):
    """Bad input for the whole matrix (printed as one line, exit status 2)."""


# --- drives ------------------------------------------------------------------------------------

class World:
    def __init__(self, label, path=None):
        self.label = label
        self.path = path  # None: the procedural city

    def __eq__(self, other):
        return isinstance(other, World) and (self.label, self.path) == (other.label, other.path)

    def __hash__(self):
        return hash((self.label, self.path))

    def __repr__(self):
        return "World(%r, %r)" % (self.label, self.path)


def parse_world(spec, base=None):
    """'city', 'karlsruhe', 'LABEL=FILE' or 'FILE' (relative to base, default the cwd)."""
    spec = spec.strip()
    if spec == "city":
        return World("city")
    if spec == "karlsruhe":
        return World("karlsruhe", os.path.normpath(os.path.join(REPO, KARLSRUHE)))
    label = None
    if "=" in spec:
        label, spec = spec.split("=", 1)
    path = os.path.normpath(os.path.join(base or os.getcwd(), os.path.expanduser(spec)))
    if label is None:
        if os.path.realpath(path) == os.path.realpath(os.path.join(REPO, KARLSRUHE)):
            label = "karlsruhe"
        else:
            label = os.path.basename(path)
            for ext in (".osm.pbf", ".pbf", ".osm"):
                if label.endswith(ext):
                    label = label[: -len(ext)]
                    break
    label = re.sub(r"[^A-Za-z0-9_.+-]", "-", label) or "world"
    return World(label, path)


def fmt_num(x):
    """0.05 -> '0.05', 2.0 -> '2'."""
    return ("%g" % x) if isinstance(x, float) else str(x)


class Drive:
    def __init__(self, world, seed, length, prior_model=SIM_DEFAULTS["prior_model"],
                 sensor=SIM_DEFAULTS["sensor"], gnss=SIM_DEFAULTS["gnss"],
                 manoeuvres=SIM_DEFAULTS["manoeuvres"], drop_scans=SIM_DEFAULTS["drop_scans"],
                 dropout_burst=SIM_DEFAULTS["dropout_burst"], map_shift=SIM_DEFAULTS["map_shift"]):
        self.world = world
        self.seed = int(seed)
        self.length = int(length)
        self.prior_model = prior_model
        self.sensor = sensor
        self.gnss = gnss
        self.manoeuvres = manoeuvres
        self.drop_scans = float(drop_scans)
        self.dropout_burst = parse_burst(dropout_burst)
        self.map_shift = float(map_shift)

    def replaced(self, **changes):
        fields = {"world": self.world, "seed": self.seed, "length": self.length,
                  "prior_model": self.prior_model, "sensor": self.sensor, "gnss": self.gnss,
                  "manoeuvres": self.manoeuvres, "drop_scans": self.drop_scans,
                  "dropout_burst": self.dropout_burst, "map_shift": self.map_shift}
        fields.update(changes)
        return Drive(**fields)

    def key(self):
        return (self.world, self.seed, self.length, self.prior_model, self.sensor, self.gnss,
                self.manoeuvres, self.drop_scans, self.dropout_burst, self.map_shift)

    def __eq__(self, other):
        return isinstance(other, Drive) and self.key() == other.key()

    def __hash__(self):
        return hash(self.key())

    def __repr__(self):
        return "Drive(%s)" % self.name

    @property
    def name(self):
        """The folder name: every parameter, default manoeuvres/drops left out."""
        parts = [self.world.label, "s%d" % self.seed, "%dm" % self.length, self.prior_model,
                 self.sensor, self.gnss]
        if self.manoeuvres != SIM_DEFAULTS["manoeuvres"]:
            parts.append("man-" + self.manoeuvres.replace(",", "+"))
        if self.drop_scans > 0:
            parts.append("drop" + fmt_num(self.drop_scans))
        if self.dropout_burst != SIM_DEFAULTS["dropout_burst"]:
            parts.append("burst" + str(self.dropout_burst).replace("@", "at"))
        if self.map_shift > 0:
            parts.append("shift" + fmt_num(self.map_shift))
        return re.sub(r"[^A-Za-z0-9_.+-]", "-", "_".join(parts))

    def sim_flags(self):
        """simulate_urban options of the drive's axes (without --out and --sim-args)."""
        flags = ["--seed", str(self.seed), "--length", str(self.length)]
        if self.world.path:
            flags += ["--osm", self.world.path]
        flags += self.new_flags()
        return flags

    def new_flags(self):
        """The flags that are not at their default (those a simulator may not know yet)."""
        flags = []
        if self.prior_model != SIM_DEFAULTS["prior_model"]:
            flags += ["--prior-model", self.prior_model]
        if self.sensor != SIM_DEFAULTS["sensor"]:
            flags += ["--sensor", self.sensor]
        if self.gnss == "rtk":
            flags.append("--rtk")
        if self.manoeuvres != SIM_DEFAULTS["manoeuvres"]:
            flags += ["--manoeuvres", self.manoeuvres]
        if self.drop_scans > 0:
            flags += ["--drop-scans", fmt_num(self.drop_scans)]
        if self.dropout_burst != SIM_DEFAULTS["dropout_burst"]:
            flags += ["--dropout-burst", str(self.dropout_burst)]
        if self.map_shift > 0:
            flags += ["--prior-global-offset", "%s,%s" % (fmt_num(self.map_shift), fmt_num(self.map_shift))]
        return flags

    def axes(self):
        return {"drive": self.name, "world": self.world.label, "world_file": self.world.path,
                "seed": self.seed, "length_m": self.length, "prior_model": self.prior_model,
                "sensor": self.sensor, "gnss": self.gnss, "manoeuvres": self.manoeuvres,
                "drop_scans": self.drop_scans, "dropout_burst": self.dropout_burst,
                "map_shift": self.map_shift}

    def estimated_scans(self):
        label = self.world.label
        scans = max(MIN_SCANS.get(label, MIN_SCANS_OTHER),
                    self.length * SCANS_PER_M.get(label, SCANS_PER_M_OTHER))
        if self.manoeuvres == "all":
            scans += MANOEUVRES_ALL_S * 10.0
        elif self.manoeuvres != "none":
            scans += MANOEUVRE_S * 10.0 * len(self.manoeuvres.split(","))
        return scans

    def estimated_seconds(self):
        """Wall time with both cores: simulate, two offline_slam passes, evaluate."""
        scans = self.estimated_scans()
        return scans / SIM_SCANS_PER_S + 2 * scans / SLAM_SCANS_PER_S + DRIVE_OVERHEAD_S


BURST = re.compile(r"^(\d+)(@\d+(\.\d*)?)?$")


def parse_burst(value):
    """simulate_urban --dropout-burst N[@T]: N (int) or 'N@T'; 0 = no burst."""
    text = str(value).strip()
    m = BURST.match(text)
    if not m:
        raise MatrixError("--dropout-burst takes N or N@T (scans, seconds), not '%s'" % text)
    return int(text) if not m.group(2) else text


def diagonal_combinations(lists):
    """Every combination of the lists, ordered so that consecutive ones differ in every axis
    that can: combination t takes from axis a the value (d_0 + ... + d_a) mod n_a, where d are
    the mixed-radix digits of t (a bijection, so each combination appears once)."""
    sizes = [len(x) for x in lists]
    total = 1
    for n in sizes:
        total *= n
    out = []
    for t in range(total):
        digits, rest = [], t
        for n in sizes:
            digits.append(rest % n)
            rest //= n
        out.append(tuple(lists[a][sum(digits[: a + 1]) % sizes[a]] for a in range(len(lists))))
    return out


def build_grid(axes, design, per_cell_short=1, per_cell_long=1, scenarios=None, extra_drives=None):
    """The drives of a matrix. design 'product': every combination of the axes. 'rotation':
    every world x seed x length x (gnss, manoeuvres, drops, map shift) cell gets per_cell (prior
    model, sensor) pairs in diagonal rotation, the rotation running on across the cells of one
    length, so every pair appears and every prior model and sensor meets each world and each
    length. scenarios (dicts of Drive fields): each drive once per scenario, with its values.
    extra_drives (dicts of Drive fields but the world): one more drive per world each."""
    def cells(lengths):
        return itertools.product(axes["worlds"], axes["seeds"], lengths, axes["gnss"],
                                 axes["manoeuvres"], axes["drop_scans"], axes["dropout_burst"],
                                 axes["map_shifts"])

    drives = []
    if design == "product":
        for w, s, l, g, m, d, b, shift in cells(axes["lengths"]):
            for p, sensor in itertools.product(axes["prior_models"], axes["sensors"]):
                drives.append(Drive(w, s, l, p, sensor, g, m, d, b, shift))
    elif design == "rotation":
        pairs = diagonal_combinations([axes[a] for a in ROTATED])
        for length in axes["lengths"]:
            per_cell = per_cell_long if length >= LONG_DRIVE_M else per_cell_short
            per_cell = max(1, min(per_cell, len(pairs)))
            t = 0
            for w, s, l, g, m, d, b, shift in cells([length]):
                for _ in range(per_cell):
                    p, sensor = pairs[t % len(pairs)]
                    t += 1
                    drives.append(Drive(w, s, l, p, sensor, g, m, d, b, shift))
    else:
        raise MatrixError("unknown design '%s'" % design)
    if scenarios:
        drives = [d.replaced(**sc) for d in drives for sc in scenarios]
    drives += [Drive(w, **fields) for w in axes["worlds"] for fields in extra_drives or []]
    # One drive per parameter set, in table order: world, length, seed, then the rest.
    unique = list(dict.fromkeys(drives))
    worlds = list(dict.fromkeys(axes["worlds"]))
    lengths = list(dict.fromkeys(list(axes["lengths"]) + sorted(d.length for d in unique)))
    return sorted(unique, key=lambda d: (worlds.index(d.world), lengths.index(d.length), d.seed))


def split_values(values, convert, split=True):
    out = []
    for v in values or []:
        for part in (v.split(",") if split else [v]):
            part = part.strip()
            if part:
                out.append(convert(part))
    return out


def axes_from_args(args):
    """(axes, design, per_cell_short, per_cell_long, scenarios, extra_drives): the preset's axes,
    explicit ones replacing theirs (and their values in the preset's scenarios; any explicit axis
    but the worlds drops the preset's extra drives); without a preset the product of the given
    axes (defaults for the others)."""
    scenarios, extras = None, []
    if args.preset:
        p = PRESETS[args.preset]
        axes = {a: list(p[a]) for a in AXES}
        axes["worlds"] = [parse_world(w, REPO) for w in axes["worlds"]]
        design, short, long_ = p["design"], p.get("per_cell_short", 1), p.get("per_cell_long", 1)
        scenarios = [dict(sc) for sc in p.get("scenarios", [])]
        extras = [dict(x) for x in p.get("extra_drives", [])]
    else:
        axes = {"worlds": [World("city")], "seeds": [1], "lengths": [300],
                "prior_models": [SIM_DEFAULTS["prior_model"]], "sensors": [SIM_DEFAULTS["sensor"]],
                "gnss": [SIM_DEFAULTS["gnss"]], "manoeuvres": [SIM_DEFAULTS["manoeuvres"]],
                "drop_scans": [SIM_DEFAULTS["drop_scans"]],
                "dropout_burst": [SIM_DEFAULTS["dropout_burst"]],
                "map_shifts": [SIM_DEFAULTS["map_shift"]]}
        design, short, long_ = "product", 1, 1

    def choice(allowed, what):
        def convert(v):
            if v not in allowed:
                raise MatrixError("unknown %s '%s' (one of %s)" % (what, v, ", ".join(allowed)))
            return v
        return convert

    def number(kind, what, minimum):
        def convert(v):
            try:
                x = kind(v)
            except ValueError:
                raise MatrixError("%s takes a number, not '%s'" % (what, v)) from None
            if x < minimum:
                raise MatrixError("%s must be at least %s, not '%s'" % (what, minimum, v))
            return x
        return convert

    # --world takes a comma list like the other axes ("karlsruhe,city"); a file whose name holds
    # a comma can still be given with --osm.
    worlds = [parse_world(w) for spec in (args.world or []) for w in spec.split(",") if w.strip()]
    worlds += [parse_world(w) for w in (args.osm or [])]
    explicit = {
        "worlds": worlds,
        "seeds": split_values(args.seed, number(int, "--seed", 0)),
        "lengths": split_values(args.length, number(int, "--length", 1)),
        "prior_models": split_values(args.prior_model, choice(PRIOR_MODELS, "prior model")),
        "sensors": split_values(args.sensor, choice(SENSORS, "sensor")),
        "gnss": split_values(args.gnss, choice(GNSS_MODES, "GNSS mode")),
        # a manoeuvre list has commas of its own: one value per --manoeuvres
        "manoeuvres": split_values(args.manoeuvres, str, split=False),
        "drop_scans": split_values(args.drop_scans, number(float, "--drop-scans", 0.0)),
        "dropout_burst": split_values(args.dropout_burst, parse_burst),
        "map_shifts": split_values(args.map_shift, number(float, "--map-shift", 0.0)),
    }
    for a, values in explicit.items():
        if values:
            axes[a] = list(dict.fromkeys(values))
            for sc in scenarios or []:
                sc.pop(a, None)
            if a != "worlds":
                extras = []
    for d in axes["drop_scans"]:
        if d >= 1.0:
            raise MatrixError("--drop-scans is a fraction below 1, not '%s'" % d)
    return axes, design, short, long_, scenarios, extras


# --- reading the results -----------------------------------------------------------------------

def dig(doc, *path):
    """doc[path[0]][path[1]]... or None when anything is missing or not a number/dict."""
    for key in path:
        if not isinstance(doc, dict) or key not in doc:
            return None
        doc = doc[key]
    return doc


def number_or_none(x):
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return None
    return None if (isinstance(x, float) and not math.isfinite(x)) else x


def ratio(a, b):
    if a is None or b is None or b <= 0:
        return None
    return a / b


def baseline_block(evaluation, label=BASELINE_LABEL):
    block = dig(evaluation, label)
    if isinstance(block, dict):
        return block, label
    for key, value in (evaluation or {}).items():  # another label: any trajectory block
        if key != "slam" and isinstance(value, dict) and "ate_m" in value:
            return value, key
    return None, label


def parse_metrics(evaluation, timing_osm=None, timing_no_osm=None, sim_info=None,
                  own_coverage=None):
    """One row's numbers from evaluate_slam --json, offline_slam's timing.json (with and without
    OSM), simulate_urban's sim_info.json and the matrix's own coverage (used when evaluate_slam
    has none). Any missing key gives None (shown as '-')."""
    ev = evaluation if isinstance(evaluation, dict) else {}
    t_osm = timing_osm if isinstance(timing_osm, dict) else {}
    sim = sim_info if isinstance(sim_info, dict) else {}
    base, label = baseline_block(ev)
    n = number_or_none
    m = {}

    cov = dig(ev, "coverage")
    if isinstance(cov, dict) and n(cov.get("fraction")) is not None:
        m["coverage"] = n(cov.get("fraction"))
        m["coverage_source"] = "evaluate_slam"
        m["longest_gap_s"] = n(cov.get("longest_gap_s"))
        m["longest_gap_m"] = n(cov.get("longest_gap_m"))
        m["untracked_scans"] = n(cov.get("untracked_scans"))
    elif isinstance(own_coverage, dict) and n(own_coverage.get("fraction")) is not None:
        m["coverage"] = n(own_coverage.get("fraction"))
        m["coverage_source"] = "matrix (estimate span / drive span)"
        m["longest_gap_s"] = n(own_coverage.get("longest_gap_s"))
        m["longest_gap_m"] = None
        m["untracked_scans"] = None
    else:
        m["coverage"] = m["longest_gap_s"] = m["longest_gap_m"] = m["untracked_scans"] = None
        m["coverage_source"] = None

    m["keyframes"] = n(t_osm.get("keyframes"))
    loops = dig(ev, "loops")
    loops = loops if isinstance(loops, dict) else {}
    m["loops"] = n(loops.get("accepted"))
    if m["loops"] is None:
        m["loops"] = n(t_osm.get("loops"))
    m["revisits"] = n(loops.get("revisits"))
    if m["revisits"] is None:
        m["revisits"] = n(sim.get("revisits"))
    m["revisits_closed"] = n(loops.get("revisits_closed"))
    m["recall"] = n(loops.get("recall"))
    if m["recall"] is None and m["revisits_closed"] is not None:
        m["recall"] = ratio(m["revisits_closed"], n(loops.get("revisits")))
    m["false_loops"] = n(loops.get("false"))

    m["ate_osm"] = n(dig(ev, "slam", "ate_m", "mean"))
    m["ate_no_osm"] = n(dig(base, "ate_m", "mean")) if base else None
    change = n(ev.get("ate_change_vs_" + label))
    if change is None:
        r = ratio(m["ate_osm"], m["ate_no_osm"])
        change = None if r is None else r - 1.0
    m["ate_change_pct"] = None if change is None else 100.0 * change
    m["ate_ratio"] = ratio(m["ate_osm"], m["ate_no_osm"])
    m["rpe_osm"] = n(dig(ev, "slam", "rpe_trans_m", "mean"))
    m["rpe_no_osm"] = n(dig(base, "rpe_trans_m", "mean")) if base else None
    m["rpe_ratio"] = ratio(m["rpe_osm"], m["rpe_no_osm"])
    m["height_drift"] = n(dig(ev, "slam", "height_drift_m", "mean"))
    tilt = n(dig(ev, "slam", "tilt_rad", "mean"))
    m["tilt_deg"] = None if tilt is None else math.degrees(tilt)

    m["bld_prior"] = n(dig(ev, "buildings_prior", "mean_corner_error_m"))
    m["bld_corrected"] = n(dig(ev, "buildings_corrected", "mean_corner_error_m"))
    m["bld_matched"] = n(dig(ev, "buildings_corrected", "matched"))
    m["seen_prior"] = n(dig(ev, "buildings_prior_observed", "mean_corner_error_m"))
    m["seen_corrected"] = n(dig(ev, "buildings_corrected_observed", "mean_corner_error_m"))
    m["seen_shape"] = n(dig(ev, "buildings_corrected_observed", "mean_corner_error_shape_m"))
    m["seen_matched"] = n(dig(ev, "buildings_corrected_observed", "matched"))
    m["overlaps"] = n(dig(ev, "buildings_corrected", "overlapping_pairs"))
    m["overlaps_prior"] = n(dig(ev, "buildings_prior", "overlapping_pairs"))

    m["scans"] = n(sim.get("scans"))
    if m["scans"] is None:
        m["scans"] = n(t_osm.get("scans"))
    m["route_m"] = n(sim.get("route_length_m"))
    m["scans_per_s"] = n(t_osm.get("scans_per_second"))
    tracking = t_osm.get("tracking")
    m["tracking"] = tracking if isinstance(tracking, dict) else None
    m["lost_events"] = n(dig(t_osm, "tracking", "lost_events"))
    return m


# --- ground truth and coverage -----------------------------------------------------------------

WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)


def ecef(lat, lon, alt):
    la, lo = math.radians(lat), math.radians(lon)
    n = WGS84_A / math.sqrt(1.0 - WGS84_E2 * math.sin(la) ** 2)
    return ((n + alt) * math.cos(la) * math.cos(lo), (n + alt) * math.cos(la) * math.sin(lo),
            (n * (1.0 - WGS84_E2) + alt) * math.sin(la))


def enu_rotation(lat, lon):
    """Rows: east, north, up in ECEF."""
    la, lo = math.radians(lat), math.radians(lon)
    return ((-math.sin(lo), math.cos(lo), 0.0),
            (-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la)),
            (math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)))


def matmul(a, b):
    return tuple(tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)) for i in range(3))


def matvec(a, v):
    return tuple(sum(a[i][k] * v[k] for k in range(3)) for i in range(3))


def transpose(a):
    return tuple(tuple(a[j][i] for j in range(3)) for i in range(3))


def quaternion(r):
    """(qx, qy, qz, qw) of a rotation matrix."""
    tr = r[0][0] + r[1][1] + r[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        return ((r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s, 0.25 * s)
    if r[0][0] > r[1][1] and r[0][0] > r[2][2]:
        s = math.sqrt(1.0 + r[0][0] - r[1][1] - r[2][2]) * 2
        return (0.25 * s, (r[0][1] + r[1][0]) / s, (r[0][2] + r[2][0]) / s, (r[2][1] - r[1][2]) / s)
    if r[1][1] > r[2][2]:
        s = math.sqrt(1.0 + r[1][1] - r[0][0] - r[2][2]) * 2
        return ((r[0][1] + r[1][0]) / s, 0.25 * s, (r[1][2] + r[2][1]) / s, (r[0][2] - r[2][0]) / s)
    s = math.sqrt(1.0 + r[2][2] - r[0][0] - r[1][1]) * 2
    return ((r[0][2] + r[2][0]) / s, (r[1][2] + r[2][1]) / s, 0.25 * s, (r[1][0] - r[0][1]) / s)


KITTI_STAMP = re.compile(r"^(\d+)-(\d+)-(\d+) (\d+):(\d+):(\d+)(?:\.(\d+))?\s*$")


def kitti_stamp_ns(text):
    """'2020-01-01 12:00:00.100000000' (UTC) -> integer nanoseconds, as kitti_raw.cpp reads it."""
    m = KITTI_STAMP.match(text)
    if not m:
        raise ValueError("malformed KITTI timestamp '%s'" % text.strip())
    secs = calendar.timegm(tuple(int(m.group(i)) for i in range(1, 7)) + (0, 0, 0))
    frac = (m.group(7) or "0")[:9].ljust(9, "0")
    return secs * 1000000000 + int(frac)


def stamp_text(ns):
    return "%d.%09d" % (ns // 1000000000, ns % 1000000000)


def write_full_ground_truth(sim_dir, drive_dir, out_path):
    """The true base_link pose of every scan (TUM) in offline_slam's map frame, ENU at the
    first OXTS fix: simulate_urban's ground_truth/poses_imu.txt (ENU at sim_info's origin) moved
    through ECEF. offline_slam's own ground_truth_tum.txt has only the estimate's keyframes, so
    it cannot show a gap in the estimate; this one has the whole drive. Returns the pose count."""
    with open(os.path.join(sim_dir, "sim_info.json")) as f:
        origin = json.load(f)["enu_origin"]
    first = first_fix(drive_dir)
    if first is None:
        raise ValueError("no OXTS record with a GNSS fix")
    with open(os.path.join(drive_dir, "oxts", "timestamps.txt")) as f:
        stamps = [kitti_stamp_ns(line) for line in f if line.strip()]
    with open(os.path.join(sim_dir, "ground_truth", "poses_imu.txt")) as f:
        poses = [[float(x) for x in line.split()] for line in f if line.strip()]
    if len(poses) != len(stamps) or not poses:
        raise ValueError("%d ground-truth poses for %d timestamps" % (len(poses), len(stamps)))
    r_sim = enu_rotation(origin["lat"], origin["lon"])
    r_map = enu_rotation(first[0], first[1])
    o_sim = ecef(origin["lat"], origin["lon"], origin["alt"])
    o_map = ecef(*first)
    r_ms = matmul(r_map, transpose(r_sim))
    delta = matvec(r_map, tuple(a - b for a, b in zip(o_sim, o_map)))
    lines = []
    for ns, p in zip(stamps, poses):
        if len(p) != 12:
            raise ValueError("a ground-truth pose of %d numbers, not 12" % len(p))
        rot = ((p[0], p[1], p[2]), (p[4], p[5], p[6]), (p[8], p[9], p[10]))
        t = matvec(r_ms, (p[3], p[7], p[11]))
        t = tuple(a + b for a, b in zip(t, delta))
        q = quaternion(matmul(r_ms, rot))
        lines.append("%s %.6f %.6f %.6f %.9f %.9f %.9f %.9f" % ((stamp_text(ns),) + t + q))
    write_atomically(out_path, "\n".join(lines) + "\n")
    return len(lines)


NO_FIX_ACCURACY = 1.0e4  # OXTS pos_accuracy (field 24) of a record without a fix (kitti_raw.h)


def first_fix(drive_dir):
    """(lat, lon, alt) of the first OXTS record with a GNSS fix (offline_slam's map origin), or
    None."""
    folder = os.path.join(drive_dir, "oxts", "data")
    for name in _listdir(folder):
        try:
            with open(os.path.join(folder, name)) as f:
                v = [float(x) for x in f.read().split()]
        except (OSError, ValueError):
            return None
        if len(v) >= 3 and all(math.isfinite(x) for x in v[:3]) and not (len(v) > 23 and v[23] >= NO_FIX_ACCURACY):
            return v[0], v[1], v[2]
    return None


def read_tum_stamps(path):
    stamps = []
    with open(path) as f:
        for line in f:
            fields = line.split()
            if fields and not fields[0].startswith("#"):
                stamps.append(float(fields[0]))
    return stamps


def own_coverage(estimate_stamps, truth_stamps):
    """Fraction of the drive's time (first to last ground-truth stamp) between the estimate's
    first and last pose, and the longest interval without an estimate pose (drive start and end
    included)."""
    if len(truth_stamps) < 2:
        return None
    t0, t1 = min(truth_stamps), max(truth_stamps)
    if t1 <= t0:
        return None
    if not estimate_stamps:
        return {"fraction": 0.0, "longest_gap_s": t1 - t0}
    est = sorted(estimate_stamps)
    covered = max(0.0, min(est[-1], t1) - max(est[0], t0))
    edges = [t0] + est + [t1]
    gap = max(b - a for a, b in zip(edges, edges[1:]))
    return {"fraction": covered / (t1 - t0), "longest_gap_s": gap}


def read_tum_poses(path):
    """{stamp rounded to 1 ms: ((x, y, z), (qx, qy, qz, qw))} of a TUM trajectory file."""
    poses = {}
    with open(path) as f:
        for line in f:
            fields = line.split()
            if len(fields) >= 8 and not fields[0].startswith("#"):
                v = [float(x) for x in fields[:8]]
                poses[round(v[0], 3)] = (tuple(v[1:4]), tuple(v[4:8]))
    return poses


def quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def quat_conj(q):
    return (-q[0], -q[1], -q[2], q[3])


def quat_rotate(q, v):
    x, y, z, _ = quat_mul(quat_mul(q, (v[0], v[1], v[2], 0.0)), quat_conj(q))
    return (x, y, z)


def _angle_between(a, b):
    dot = sum(x * y for x, y in zip(a, b))
    na, nb = math.sqrt(sum(x * x for x in a)), math.sqrt(sum(x * x for x in b))
    return math.degrees(math.acos(max(-1.0, min(1.0, dot / (na * nb)))))


def orientation_errors(estimate, truth, align_first=False):
    """Heading and tilt errors [deg] of an estimate against the truth at the same stamps:
    heading = angle between the horizontal projections of the body x axes, tilt = angle between
    the body z axes. align_first rotates the estimate so that its first common pose has the
    truth's orientation (raw odometry starts at the identity). None without common stamps."""
    common = sorted(set(estimate) & set(truth))
    if not common:
        return None
    align = (0.0, 0.0, 0.0, 1.0)
    if align_first:
        align = quat_mul(truth[common[0]][1], quat_conj(estimate[common[0]][1]))
    headings, tilts = [], []
    for t in common:
        q_est, q_true = quat_mul(align, estimate[t][1]), truth[t][1]
        xe, xt = quat_rotate(q_est, (1.0, 0.0, 0.0)), quat_rotate(q_true, (1.0, 0.0, 0.0))
        d = math.atan2(xe[1], xe[0]) - math.atan2(xt[1], xt[0])
        headings.append(abs(math.degrees(math.atan2(math.sin(d), math.cos(d)))))
        tilts.append(_angle_between(quat_rotate(q_est, (0.0, 0.0, 1.0)),
                                    quat_rotate(q_true, (0.0, 0.0, 1.0))))
    return {"heading_mean": sum(headings) / len(headings), "heading_max": max(headings),
            "tilt_mean": sum(tilts) / len(tilts), "tilt_max": max(tilts)}


def orientation_metrics(osm_out, no_osm_out):
    """The trajectory's heading error (the run with OSM, as evaluated: no alignment) and the raw
    odometry's tilt drift (first pose aligned). The back-end's IMU attitude priors hide the
    odometry's tilt from every trajectory metric; the matrix shows it (doc/matrix.md, session
    15: 63 deg on a drive whose trajectory tilt was 0.04 deg)."""
    m = {"heading_deg": None, "heading_max_deg": None, "odo_tilt_deg": None}
    try:
        e = orientation_errors(read_tum_poses(os.path.join(osm_out, "trajectory_tum.txt")),
                               read_tum_poses(os.path.join(osm_out, "ground_truth_tum.txt")))
        if e:
            m["heading_deg"], m["heading_max_deg"] = e["heading_mean"], e["heading_max"]
        o = orientation_errors(read_tum_poses(os.path.join(no_osm_out, "odometry_tum.txt")),
                               read_tum_poses(os.path.join(no_osm_out, "ground_truth_tum.txt")),
                               align_first=True)
        if o:
            m["odo_tilt_deg"] = o["tilt_max"]
    except (OSError, ValueError):
        pass
    return m


def _oxts_latlon(path):
    """(lat, lon) of an OXTS record, or None for a record without a fix (pos_accuracy >= 1e3 m:
    the simulator's outages) or an unreadable one."""
    try:
        v = open(path).read().split()
        if len(v) < 24 or float(v[23]) >= 1e3:
            return None
        lat, lon = float(v[0]), float(v[1])
    except (OSError, ValueError):
        return None
    return (lat, lon) if math.isfinite(lat) and math.isfinite(lon) else None


def gnss_mean_error(drive_dir):
    """Mean horizontal (east, north) error [m] of the drive's fixes against oxts_true (the
    simulator's truth), over the records with a fix; None without them."""
    data = os.path.join(drive_dir, "oxts", "data")
    east = north = 0.0
    n = 0
    for name in _listdir(data):
        fix = _oxts_latlon(os.path.join(data, name))
        true = _oxts_latlon(os.path.join(drive_dir, "oxts_true", "data", name))
        if fix is None or true is None:
            continue
        r = 6378137.0 * math.pi / 180.0
        east += (fix[1] - true[1]) * r * math.cos(math.radians(true[0]))
        north += (fix[0] - true[0]) * r
        n += 1
    return (east / n, north / n) if n else None


def observed_prior_offset(sim_dir, corrected_geojson):
    """Mean (dx, dy) [m] of the simulator's prior offsets over the buildings the run observed
    (tag osm_graph_slam:observations > 0), and their count; None when unknown."""
    offsets = {}
    try:
        for line in open(os.path.join(sim_dir, "prior_offsets.csv")):
            v = line.strip().split(",")
            if line.startswith("#") or len(v) < 4 or v[0] == "osm_id":
                continue
            offsets[v[0]] = (float(v[2]), float(v[3]))
        features = read_json(corrected_geojson)["features"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    seen = []
    for f in features:
        props = f.get("properties") or {}
        try:
            n = int((props.get("tags") or {}).get("osm_graph_slam:observations", 0))
        except (TypeError, ValueError):
            n = 0
        if n > 0 and str(props.get("id")) in offsets:
            seen.append(offsets[str(props.get("id"))])
    if not seen:
        return None
    return (sum(o[0] for o in seen) / len(seen), sum(o[1] for o in seen) / len(seen)), len(seen)


def offset_bound(map_offset, gnss_offset):
    """The smallest common horizontal offset [m] any weighting of the two absolute references
    can reach: min over w in [0, 1] of |w m + (1 - w) b|. The walls tie the trajectory to the
    map; its absolute position can only come from the map (error m, the observed buildings'
    mean prior offset) or from the fixes (error b, their mean error over the drive)."""
    (mx, my), (bx, by) = map_offset, gnss_offset
    dx, dy = mx - bx, my - by
    length2 = dx * dx + dy * dy
    w = 0.0 if length2 == 0 else max(0.0, min(1.0, -(bx * dx + by * dy) / length2))
    return math.hypot(bx + w * dx, by + w * dy)


def absolute_offset_metrics(sim_dir, drive_dir, corrected_geojson):
    """Simulated drives only: the fixes' mean error, the observed buildings' mean prior offset
    and offset_bound() of the two ("B_bnd": no estimator's buildings or trajectory end closer
    in the mean)."""
    m = {"gnss_mean_error": None, "map_mean_offset": None, "offset_bound": None}
    b = gnss_mean_error(drive_dir)
    seen = observed_prior_offset(sim_dir, corrected_geojson)
    if b is not None:
        m["gnss_mean_error"] = math.hypot(*b)
    if seen is not None:
        m["map_mean_offset"] = math.hypot(*seen[0])
    if b is not None and seen is not None:
        m["offset_bound"] = offset_bound(seen[0], b)
    return m


# --- summary, table, check ---------------------------------------------------------------------

def f3(x):
    return "%.3f" % x


def f2(x):
    return "%.2f" % x


def f1(x):
    return "%.1f" % x


def fpct(x):
    return "%+.1f" % x


def fint(x):
    return "%d" % round(x)


# (metric, header, width, format, worst direction: "max", "min" or None = no bad direction)
COLUMNS = [
    ("coverage", "cover", 5, f2, "min"),
    ("keyframes", "kf", 5, fint, None),
    ("loops", "loops", 5, fint, None),
    ("revisits", "revis", 5, fint, None),
    ("recall", "recall", 6, f2, "min"),
    ("false_loops", "false", 5, fint, "max"),
    ("ate_osm", "ATE_osm", 7, f3, "max"),
    ("ate_no_osm", "ATE_no", 7, f3, "max"),
    ("ate_change_pct", "chg%", 7, fpct, "max"),
    ("rpe_ratio", "tRPE_r", 6, f2, "max"),
    ("height_drift", "z_dr", 5, f3, "max"),
    ("tilt_deg", "tilt", 5, f3, "max"),
    ("heading_deg", "hdg", 5, f2, "max"),
    ("odo_tilt_deg", "oTilt", 5, f1, "max"),
    ("bld_prior", "B_prior", 7, f3, "max"),
    ("bld_corrected", "B_corr", 7, f3, "max"),
    ("seen_prior", "S_prior", 7, f3, "max"),
    ("seen_corrected", "S_corr", 7, f3, "max"),
    ("seen_shape", "S_shp", 5, f2, "max"),
    ("offset_bound", "B_bnd", 5, f2, "max"),
    ("overlaps", "ovl", 4, fint, "max"),
    ("scans_per_s", "sc/s", 5, f1, "min"),
]


def is_ok(row):
    return row.get("status") == "ok"


def summarize(rows):
    """{metric: {"median", "worst", "worst_drive"}} over the rows with status ok."""
    out = {}
    for key, _, _, _, direction in COLUMNS:
        vals = [(r["metrics"][key], r["drive"]) for r in rows
                if is_ok(r) and number_or_none((r.get("metrics") or {}).get(key)) is not None]
        entry = {"median": None, "worst": None, "worst_drive": None, "count": len(vals)}
        if vals:
            entry["median"] = statistics.median(v for v, _ in vals)
            if direction:
                pick = max if direction == "max" else min
                v, d = pick(vals, key=lambda x: x[0])
                entry["worst"], entry["worst_drive"] = v, d
        out[key] = entry
    return out


def worst_drive(rows):
    """(drive, why) of the finished drive whose OSM run did worst against its baseline: the
    largest ATE change. Drives that did not finish are listed apart."""
    scored = [r for r in rows if is_ok(r)
              and number_or_none((r.get("metrics") or {}).get("ate_change_pct")) is not None]
    if not scored:
        return None, None
    r = max(scored, key=lambda r: r["metrics"]["ate_change_pct"])
    return r["drive"], "ATE change %+.1f %% vs %s (ATE %.3f m with OSM, %.3f m without)" % (
        r["metrics"]["ate_change_pct"], BASELINE_LABEL, r["metrics"].get("ate_osm") or 0.0,
        r["metrics"].get("ate_no_osm") or 0.0)


AXIS_COLUMNS = [("#", 3), ("world", 10), ("seed", 4), ("len", 5), ("prior", 11), ("sensor", 6),
                ("gnss", 5)]


def format_table(rows, summary=None):
    extra = []
    if any(r.get("manoeuvres", SIM_DEFAULTS["manoeuvres"]) != SIM_DEFAULTS["manoeuvres"] for r in rows):
        extra.append(("manoeuvres", 16))
    if any((r.get("drop_scans") or 0) > 0 or r.get("dropout_burst") not in (None, 0) for r in rows):
        extra.append(("drops", 10))
    if any((r.get("map_shift") or 0) > 0 for r in rows):
        extra.append(("shift", 5))
    head = [h.ljust(w) if h in ("world", "prior", "sensor", "gnss", "manoeuvres", "drops") else h.rjust(w)
            for h, w in AXIS_COLUMNS + extra]
    head += [h.rjust(w) for _, h, w, _, _ in COLUMNS] + ["status"]
    lines = [" ".join(head)]

    def cut(text, width):
        return text if len(text) <= width else text[: width - 1] + "~"

    for i, r in enumerate(rows, 1):
        cells = ["%3d" % i, cut(str(r.get("world", "?")), 10).ljust(10), str(r.get("seed", "?")).rjust(4),
                 str(r.get("length_m", "?")).rjust(5), cut(str(r.get("prior_model", "?")), 11).ljust(11),
                 cut(str(r.get("sensor", "?")), 6).ljust(6), cut(str(r.get("gnss", "?")), 5).ljust(5)]
        for name, w in extra:
            if name == "manoeuvres":
                cells.append(cut(str(r.get("manoeuvres", "")), w).ljust(w))
            elif name == "shift":
                shift = r.get("map_shift") or 0
                cells.append((fmt_num(float(shift)) if shift > 0 else "-").rjust(w))
            else:
                d, burst = r.get("drop_scans") or 0, r.get("dropout_burst") or 0
                parts = ([fmt_num(float(d))] if d > 0 else []) + (["b%s" % burst] if burst else [])
                text = "+".join(parts) or "-"
                cells.append(cut(text, w).ljust(w))
        metrics = r.get("metrics") or {}
        for key, _, w, fmt, _ in COLUMNS:
            v = number_or_none(metrics.get(key))
            cells.append(("-" if v is None else fmt(v)).rjust(w))
        cells.append(str(r.get("status", "?")))
        lines.append(" ".join(cells))
    if summary is not None:
        pad = sum(w + 1 for _, w in AXIS_COLUMNS + extra) - 1
        for label in ("median", "worst"):
            cells = [label.ljust(pad)]
            for key, _, w, fmt, direction in COLUMNS:
                v = summary[key][label]
                cells.append(("-" if v is None else fmt(v)).rjust(w))
            lines.append(" ".join(cells))
    return "\n".join(lines)


LIMITS = [  # (option attribute, metric, bad when, text)
    ("max_ate_ratio", "ate_ratio", "above", "ATE with OSM / without"),
    ("max_rpe_ratio", "rpe_ratio", "above", "t-RPE with OSM / without"),
    ("min_coverage", "coverage", "below", "coverage"),
    ("max_false_loops", "false_loops", "above", "false loops"),
    ("max_building_error", "bld_corrected", "above", "corrected buildings' mean corner error [m]"),
]


def check_rows(rows, limits):
    """Violations of the limits ({option attribute: value or None}) as lines naming the drive
    and the limit. A drive that did not finish, or whose metric was not measured, violates."""
    violations = []
    active = [(a, m, how, text) for a, m, how, text in LIMITS if limits.get(a) is not None]
    if not active:
        return violations
    for r in rows:
        if not is_ok(r):
            violations.append("%s: did not finish (%s)" % (r["drive"], r.get("status", "?")))
            continue
        metrics = r.get("metrics") or {}
        for attr, metric, how, text in active:
            limit = limits[attr]
            option = "--" + attr.replace("_", "-")
            v = number_or_none(metrics.get(metric))
            if v is None:
                violations.append("%s: %s not measured (%s %g)" % (r["drive"], text, option, limit))
            elif (how == "above" and v > limit) or (how == "below" and v < limit):
                violations.append("%s: %s %.3f %s %s %g" % (r["drive"], text, v,
                                                            ">" if how == "above" else "<", option, limit))
    return violations


# --- running one drive ---------------------------------------------------------------------------

def write_atomically(path, text):
    tmp = "%s.tmp.%d.%d" % (path, os.getpid(), threading.get_ident())
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def read_json(path):
    """The document, or None when the file is missing or unreadable."""
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


def last_log_line(path):
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            f.seek(max(0, size - 16384))
            text = f.read().decode("utf-8", "replace")
    except OSError:
        return ""
    for line in reversed(re.split(r"[\r\n]+", ANSI.sub("", text))):
        line = line.strip()
        if line and not re.fullmatch(r"\[[# ]*\]\s*\d+/\d+", line):  # skip progress bars
            return line[:300]
    return ""


class StepFailed(Exception):
    pass


class Stopped(Exception):
    pass


class Context:
    """What every drive needs: tools, folders, options, and the child processes to stop."""

    def __init__(self, bin_dir, config, out, sim_args, keep=False, step_timeout=None,
                 eval_options=(), dump=False, replay_from=None, replay_sets=()):
        self.bin_dir = bin_dir
        self.replay_from = replay_from  # --replay: re-run only the back-ends on FROM's dumps
        self.replay_sets = list(replay_sets)
        self.dump = dump  # offline_slam --dump into slam_osm/dump and slam_no_osm/dump
        self.config = config
        self.out = out
        self.sim_args = sim_args
        self.keep = keep
        self.step_timeout = step_timeout
        self.eval_options = set(eval_options)  # evaluate_slam options this build knows
        self.stopping = threading.Event()
        self._lock = threading.Lock()
        self._procs = set()

    def tool(self, name):
        return os.path.join(self.bin_dir, name)

    def run(self, step, cmd, log_path, stdout_path=None):
        """Runs cmd (own process group) with its output in log_path (stdout to stdout_path when
        given); StepFailed names the step, the status and the log's last line."""
        if self.stopping.is_set():
            raise Stopped()
        with open(log_path, "ab") as log:
            log.write(("$ %s\n" % " ".join(shlex.quote(c) for c in cmd)).encode())
            log.flush()
            out = open(stdout_path, "wb") if stdout_path else log
            try:
                try:
                    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out, stderr=log,
                                            start_new_session=True)
                except OSError as e:
                    raise StepFailed("%s: cannot start %s: %s" % (step, cmd[0], e.strerror)) from None
                with self._lock:
                    self._procs.add(proc)
                try:
                    code = proc.wait(timeout=self.step_timeout)
                except subprocess.TimeoutExpired:
                    self._stop(proc)
                    raise StepFailed("%s: no result after %g s (stopped)" % (step, self.step_timeout)) from None
                finally:
                    with self._lock:
                        self._procs.discard(proc)
            finally:
                if stdout_path:
                    out.close()
        if self.stopping.is_set():
            raise Stopped()
        if code == 0:
            return
        tool = os.path.basename(cmd[0])
        last = last_log_line(log_path)
        if code < 0:
            try:
                sig = signal.Signals(-code).name
            except ValueError:
                sig = "signal %d" % -code
            why = "%s crashed (%s)" % (tool, sig)
        else:
            why = "%s exited with status %d" % (tool, code)
        raise StepFailed("%s: %s: %s" % (step, why, last or "(empty log)"))

    @staticmethod
    def _stop(proc):
        for sig, wait in ((signal.SIGTERM, 5), (signal.SIGKILL, 5)):
            try:
                os.killpg(proc.pid, sig)
            except (ProcessLookupError, PermissionError):
                return
            try:
                proc.wait(timeout=wait)
                return
            except subprocess.TimeoutExpired:
                pass

    def stop_all(self):
        """Stops every running step (only the process groups this script started)."""
        self.stopping.set()
        with self._lock:
            procs = list(self._procs)
        threads = [threading.Thread(target=self._stop, args=(p,)) for p in procs]
        for t in threads:
            t.start()
        for t in threads:
            t.join()


def drive_row(drive, status, metrics=None, steps=None):
    row = drive.axes()
    row["status"] = status
    row["metrics"] = metrics or {}
    row["step_seconds"] = steps or {}
    return row


def world_problem(drive):
    if drive.world.path is None:
        return None
    if not os.path.isfile(drive.world.path):
        return "error: world file missing: %s" % drive.world.path
    if not os.access(drive.world.path, os.R_OK):
        return "error: world file unreadable: %s" % drive.world.path
    return None


def rejected_flags_hint(drive, log_path):
    """simulate_urban prints its usage (status 2) for an option it does not know: today naming it
    ("unknown option '--x'"), older builds listing the options they know."""
    try:
        with open(log_path, errors="replace") as f:
            text = "".join(line for line in f if not line.startswith("$ "))  # not our command line
    except OSError:
        return None
    if "usage:" not in text:
        return None
    named = re.findall(r"unknown option '(--[\w-]+)'", text)
    if named:
        unknown = [f for f in drive.new_flags() if f in named]
    else:
        unknown = [f for f in drive.new_flags() if f.startswith("--") and f not in text]
    if unknown:
        return ("simulate: simulate_urban does not know %s (printed its usage; not built yet?)"
                % " ".join(unknown))
    return "simulate: simulate_urban rejected its arguments (printed its usage; see logs/simulate_urban.log)"


def unwritable(folder):
    """None when `folder` exists (made if needed) and takes a file; else the reason."""
    try:
        os.makedirs(folder, exist_ok=True)
        probe = os.path.join(folder, ".slam_matrix_write_test")
        with open(probe, "w"):
            pass
        os.remove(probe)
    except OSError as e:
        return str(e.strerror or e)
    return None


def run_drive(drive, ctx, force=False):
    """Runs one drive in ctx.out/<drive.name> and returns its row. Never raises for bad input or
    failing tools: the row's status says what went wrong."""
    problem = world_problem(drive)
    if problem:
        return drive_row(drive, problem)
    d = os.path.join(ctx.out, drive.name)
    logs = os.path.join(d, "logs")
    problem = unwritable(logs)
    if problem:
        return drive_row(drive, "error: cannot write %s: %s" % (d, problem))
    steps = {}
    try:
        return _run_drive_steps(drive, ctx, d, logs, steps, force)
    except Stopped:
        raise
    except StepFailed as e:
        status = "error: %s" % e
    except Exception as e:  # a bug or an unexpected file: one line in the table, details in the log
        status = "error: internal: %s: %s (details in logs/matrix.log)" % (type(e).__name__, e)
        try:
            with open(os.path.join(logs, "matrix.log"), "a") as f:
                f.write(traceback.format_exc())
        except OSError:
            pass
    row = drive_row(drive, status, steps=steps)
    _finish_drive(ctx, d, row)
    return row


def _clean(d):
    if os.path.islink(os.path.join(d, "sim")):  # --replay: the source's simulation
        os.remove(os.path.join(d, "sim"))
    for name in ("sim", "slam_osm", "slam_no_osm"):
        shutil.rmtree(os.path.join(d, name), ignore_errors=True)
    for name in ("evaluation.json", "ground_truth_tum.txt", "result.json"):
        try:
            os.remove(os.path.join(d, name))
        except FileNotFoundError:
            pass
    for name in os.listdir(os.path.join(d, "logs")):
        try:
            os.remove(os.path.join(d, "logs", name))
        except OSError:
            pass


def _timed(steps, name, fn):
    t0 = time.monotonic()
    fn()
    steps[name] = round(time.monotonic() - t0, 1)


def _run_drive_steps(drive, ctx, d, logs, steps, force):
    _clean(d)
    write_atomically(os.path.join(d, "drive.json"), json.dumps(drive.axes(), indent=2) + "\n")
    if ctx.replay_from:
        sim, drive_dir = _replay_backends(drive, ctx, d, logs, steps)
    else:
        sim, drive_dir = _simulate_and_run_slam(drive, ctx, d, logs, steps)
    return _evaluate_drive(drive, ctx, d, logs, steps, sim, drive_dir)


def _find_drive_dir(sim):
    drives = sorted(p for p in (os.path.join(sim, a, b) for a in _listdir(sim)
                                for b in _listdir(os.path.join(sim, a)))
                    if re.search(r"_drive_\d+_sync$", p) and os.path.isdir(p))
    return drives[0] if drives else None


REPLAY_COPIED = {"slam_osm": ("ground_truth_scans_tum.txt", "ground_truth_tum.txt", "loops.txt", "timing.json"),
                 "slam_no_osm": ("ground_truth_tum.txt", "timing.json")}


def _replay_backends(drive, ctx, d, logs, steps):
    """--replay FROM: the same drive's back-end inputs (FROM/<drive>/slam_*/dump, written with
    --dump) through replay_backend with --set; the front-end's files (truth, loops, timing) and
    the simulation are taken from FROM unchanged."""
    src = os.path.join(ctx.replay_from, drive.name)
    sim = os.path.join(d, "sim")
    if not os.path.isdir(os.path.join(src, "sim")):
        raise StepFailed("replay: %s has no sim folder (run the matrix there first)" % src)
    os.symlink(os.path.join(os.path.abspath(src), "sim"), sim)
    drive_dir = _find_drive_dir(sim)
    if drive_dir is None:
        raise StepFailed("replay: no drive folder in %s" % sim)
    for run, extra in (("slam_osm", []), ("slam_no_osm", ["--no-osm"])):
        dump = os.path.join(src, run, "dump")
        if not os.path.isfile(os.path.join(dump, "keyframes.csv")):
            raise StepFailed("replay: %s missing (run the matrix there with --dump)" % dump)
        out = os.path.join(d, run)
        sets = [a for kv in ctx.replay_sets for a in ("--set", kv)]
        _timed(steps, "replay_" + run, lambda: ctx.run(
            "replay_backend (%s)" % run, [ctx.tool("replay_backend"), "--dump", dump, "--output", out,
                                          "--config", ctx.config] + extra + sets,
            os.path.join(logs, "replay_%s.log" % run)))
        for name in REPLAY_COPIED[run]:
            if os.path.isfile(os.path.join(src, run, name)):
                shutil.copyfile(os.path.join(src, run, name), os.path.join(out, name))
    return sim, drive_dir


def _simulate_and_run_slam(drive, ctx, d, logs, steps):
    sim = os.path.join(d, "sim")
    sim_log = os.path.join(logs, "simulate_urban.log")
    cmd = [ctx.tool("simulate_urban"), "--out", sim] + drive.sim_flags() + ctx.sim_args
    try:
        _timed(steps, "simulate", lambda: ctx.run("simulate", cmd, sim_log))
    except StepFailed:
        hint = rejected_flags_hint(drive, sim_log)
        if hint:
            raise StepFailed(hint) from None
        raise
    drive_dir = _find_drive_dir(sim)
    if drive_dir is None:
        raise StepFailed("simulate: no drive folder in %s (%s)" % (sim, last_log_line(sim_log) or "empty log"))
    prior = os.path.join(sim, "prior.osm")

    common = [ctx.tool("offline_slam"), "--kitti-raw", drive_dir, "--config", ctx.config]
    osm_out, no_osm_out = os.path.join(d, "slam_osm"), os.path.join(d, "slam_no_osm")

    def dump(run_out):  # the back-end's inputs, for replay_backend (--replay)
        return ["--dump", os.path.join(run_out, "dump"), "--dump-without-clouds"] if ctx.dump else []

    _timed(steps, "offline_slam_osm", lambda: ctx.run(
        "offline_slam (with OSM)", common + ["--osm", prior, "--output", osm_out] + dump(osm_out),
        os.path.join(logs, "offline_slam_osm.log")))
    _timed(steps, "offline_slam_no_osm", lambda: ctx.run(
        "offline_slam --no-osm", common + ["--no-osm", "--output", no_osm_out] + dump(no_osm_out),
        os.path.join(logs, "offline_slam_no_osm.log")))
    return sim, drive_dir


def _evaluate_drive(drive, ctx, d, logs, steps, sim, drive_dir):
    prior = os.path.join(sim, "prior.osm")
    osm_out, no_osm_out = os.path.join(d, "slam_osm"), os.path.join(d, "slam_no_osm")
    # Ground truth of the whole drive, so that coverage can see where the estimate stops short:
    # offline_slam's truth of every scan (newer builds), else the simulator's true poses moved
    # into the map frame here, else offline_slam's truth of the keyframes.
    notes = []
    gt = os.path.join(osm_out, "ground_truth_scans_tum.txt")
    if not os.path.isfile(gt):
        gt = os.path.join(d, "ground_truth_tum.txt")
        try:
            write_full_ground_truth(sim, drive_dir, gt)
        except (OSError, ValueError, KeyError, TypeError) as e:
            notes.append("ground truth of the keyframes only (slam_osm/ground_truth_tum.txt): %s" % e)
            gt = os.path.join(osm_out, "ground_truth_tum.txt")
    metrics_gt = os.path.relpath(gt, d)

    eval_log = os.path.join(logs, "evaluate_slam.log")
    fix = first_fix(drive_dir)  # the map frame's origin (the plots' buildings are projected there)
    if fix is None:
        raise StepFailed("evaluate: no OXTS record with a GNSS fix in %s/oxts/data" % drive_dir)
    origin = "%.9f,%.9f" % (fix[0], fix[1])
    cmd = [ctx.tool("evaluate_slam"), "--estimate", os.path.join(osm_out, "trajectory_tum.txt"),
           "--ground-truth", gt, "--origin", origin,
           "--baseline", os.path.join(no_osm_out, "trajectory_tum.txt"), "--baseline-label", BASELINE_LABEL,
           "--buildings-true", os.path.join(sim, "buildings_true.geojson"), "--buildings-prior", prior,
           "--buildings-corrected", os.path.join(osm_out, "buildings_corrected.geojson")]
    # The newer options only when this evaluate_slam knows them and offline_slam wrote the files
    # (a timing.json without "tracking" is from an older offline_slam).
    report = os.path.join(osm_out, "timing.json")
    optional = []
    if "--run-report" in ctx.eval_options and isinstance(dig(read_json(report), "tracking"), dict):
        optional += ["--run-report", report]
    for name in ("loops.csv", "loops.txt"):
        if "--loops" in ctx.eval_options and os.path.isfile(os.path.join(osm_out, name)):
            optional += ["--loops", os.path.join(osm_out, name)]
            break
    evaluation_path = os.path.join(d, "evaluation.json")
    try:
        _timed(steps, "evaluate", lambda: ctx.run("evaluate", cmd + optional + ["--json"], eval_log,
                                                  evaluation_path))
    except StepFailed as e:
        if not optional:
            raise
        notes.append("evaluate_slam failed with %s (%s); evaluated without them" % (" ".join(optional), e))
        _timed(steps, "evaluate", lambda: ctx.run("evaluate (without --run-report/--loops)", cmd + ["--json"],
                                                  eval_log, evaluation_path))
    evaluation = read_json(evaluation_path)
    if not isinstance(evaluation, dict):
        raise StepFailed("evaluate: evaluation.json is not JSON: %s" % (last_log_line(evaluation_path) or "empty"))

    try:
        coverage = own_coverage(read_tum_stamps(os.path.join(osm_out, "trajectory_tum.txt")),
                                read_tum_stamps(gt))
    except (OSError, ValueError):
        coverage = None
    metrics = parse_metrics(evaluation, read_json(report), read_json(os.path.join(no_osm_out, "timing.json")),
                            read_json(os.path.join(sim, "sim_info.json")), coverage)
    metrics["own_coverage"] = coverage
    metrics.update(orientation_metrics(osm_out, no_osm_out))
    metrics.update(absolute_offset_metrics(sim, drive_dir, os.path.join(osm_out, "buildings_corrected.geojson")))
    metrics["ground_truth"] = metrics_gt
    if notes:
        metrics["notes"] = notes
    steps["total"] = round(sum(steps.values()), 1)
    row = drive_row(drive, "ok", metrics, steps)
    _finish_drive(ctx, d, row)
    return row


def _listdir(path):
    try:
        return sorted(os.listdir(path))
    except OSError:
        return []


def _finish_drive(ctx, d, row):
    """Deletes the simulated scans (GBs for 1.5 km) unless --keep; writes result.json."""
    # --replay links the source's simulation: never delete in there (its drives may be running).
    if not ctx.keep and not os.path.islink(os.path.join(d, "sim")):
        sim = os.path.join(d, "sim")
        for a in _listdir(sim):
            for b in _listdir(os.path.join(sim, a)):
                shutil.rmtree(os.path.join(sim, a, b, "velodyne_points"), ignore_errors=True)
    row["finished"] = time.strftime("%Y-%m-%d %H:%M:%S")
    try:
        write_atomically(os.path.join(d, "result.json"), json.dumps(row, indent=2) + "\n")
    except OSError as e:
        row["status"] += " (result.json not written: %s)" % (e.strerror or e)


def load_result(drive, out):
    """The stored row of a finished drive, or None."""
    row = read_json(os.path.join(out, drive.name, "result.json"))
    if not isinstance(row, dict) or "status" not in row:
        return None
    row.update({k: v for k, v in drive.axes().items() if k not in row})
    row.setdefault("metrics", {})
    return row


# --- the matrix ----------------------------------------------------------------------------------

def evaluate_options(bin_dir):
    """Which of the newer evaluate_slam options this build knows (from its usage text)."""
    try:
        p = subprocess.Popen([os.path.join(bin_dir, "evaluate_slam"), "--help"], stdin=subprocess.DEVNULL,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    except OSError:
        return set()
    try:
        text = p.communicate(timeout=30)[0].decode("utf-8", "replace")
    except BaseException:  # a timeout or Ctrl-C: stop its whole group, then go on / re-raise
        Context._stop(p)
        if sys.exc_info()[0] is subprocess.TimeoutExpired:
            return set()
        raise
    return {o for o in ("--run-report", "--loops", "--min-coverage") if o in text}


def plan(drives, out, force=False, retry_failed=False):
    """(to_run, stored rows by drive): a drive with a result.json is not run again, unless force,
    or retry_failed and its status is not ok."""
    stored, to_run = {}, []
    for d in drives:
        row = None if force else load_result(d, out)
        if row is not None and retry_failed and not is_ok(row):
            row = None
        if row is None:
            to_run.append(d)
        else:
            stored[d] = row
    return to_run, stored


def print_flushed(text):
    print(text, flush=True)  # progress lines appear at once also when stdout is a file


def run_matrix(drives, ctx, to_run, jobs, runner=run_drive, log=print_flushed):
    """Runs the drives of to_run (longest first, `jobs` at a time); returns {drive: row}."""
    results = {}
    if not to_run:
        return results
    order = sorted(to_run, key=lambda d: -d.estimated_seconds())
    total, done = len(order), [0]
    lock = threading.Lock()

    def work(drive):
        if ctx.stopping.is_set():
            raise Stopped()
        problem = world_problem(drive)
        if not problem:
            with lock:
                log("[matrix] start %s" % drive.name)
        t0 = time.monotonic()
        row = runner(drive, ctx)
        with lock:
            done[0] += 1
            log("[matrix] %d/%d %s: %s (%.0f s)" % (done[0], total, drive.name, row["status"],
                                                    time.monotonic() - t0))
        return row

    pool = concurrent.futures.ThreadPoolExecutor(max_workers=max(1, jobs))
    futures = {pool.submit(work, d): d for d in order}
    try:
        pending = set(futures)
        while pending:
            finished, pending = concurrent.futures.wait(pending, timeout=0.5)
            for f in finished:
                d = futures[f]
                try:
                    results[d] = f.result()
                except Stopped:
                    pass
                except Exception as e:  # the runner itself failed: still one line
                    results[d] = drive_row(d, "error: internal: %s: %s" % (type(e).__name__, e))
    except KeyboardInterrupt:
        ctx.stop_all()
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return results


def estimate_text(drives, jobs):
    secs = sum(d.estimated_seconds() for d in drives)
    longest = max((d.estimated_seconds() for d in drives), default=0)
    return ("%d drives, %.0f scans; estimated %.0f min on 2 cores, --jobs %d (%.0f scans/s "
            "simulate_urban, %.0f scans/s offline_slam; longest drive %.0f min)" % (
                len(drives), sum(d.estimated_scans() for d in drives), secs / 60, jobs,
                SIM_SCANS_PER_S, SLAM_SCANS_PER_S, longest / 60))


def build_parser():
    ap = argparse.ArgumentParser(
        description="Runs simulate_urban -> offline_slam (OSM) -> offline_slam --no-osm -> "
                    "evaluate_slam over a matrix of drives; table, summary, matrix.json. "
                    "See doc/matrix.md.")
    ap.add_argument("--preset", choices=sorted(PRESETS), help="a predefined matrix; explicit axes replace its axes")
    g = ap.add_argument_group("axes (repeatable or comma-separated; without --preset: their product)")
    g.add_argument("--world", action="append", metavar="W",
                   help="city (the procedural city), karlsruhe (%s) or [LABEL=]FILE.osm" % KARLSRUHE)
    g.add_argument("--osm", action="append", metavar="FILE", help="an OSM extract as a world ([LABEL=]FILE)")
    g.add_argument("--seed", action="append", metavar="N")
    g.add_argument("--length", action="append", metavar="M", help="route length [m]")
    g.add_argument("--prior-model", action="append", metavar="P", help="|".join(PRIOR_MODELS))
    g.add_argument("--sensor", action="append", metavar="S", help="|".join(SENSORS))
    g.add_argument("--gnss", action="append", metavar="G", help="noisy (default) | rtk (simulate_urban --rtk)")
    g.add_argument("--manoeuvres", action="append", metavar="LIST",
                   help="one simulate_urban --manoeuvres value per option (none, all, sharp_turn,stop ...)")
    g.add_argument("--drop-scans", action="append", metavar="F", help="fraction of scans dropped")
    g.add_argument("--dropout-burst", action="append", metavar="N[@T]",
                   help="one burst of N consecutive missing scans (at T s); 0 = none")
    g.add_argument("--map-shift", action="append", metavar="M",
                   help="the 'global' and 'mixed' prior models' common map shift [m], fixed "
                        "(simulate_urban --prior-global-offset M,M); 0 = uniform in 1-3 m")
    ap.add_argument("--sim-args", default=DEFAULT_SIM_ARGS,
                    help="extra simulate_urban options for every drive (default: '%(default)s')")
    ap.add_argument("--bin", default=os.path.join(REPO, "build_ws", "devel", "lib", "osm_graph_slam"),
                    help="the tools' folder (default: %(default)s)")
    ap.add_argument("--config", default=os.path.join(REPO, "config", "sim.yaml"),
                    help="offline_slam --config (default: %(default)s)")
    ap.add_argument("--out", default=os.path.join(REPO, "build_ws", "matrix"), help="default: %(default)s")
    ap.add_argument("--jobs", type=int, default=1, help="drives at a time (each tool uses both cores; default 1)")
    ap.add_argument("--keep", action="store_true", help="keep the simulated scans (velodyne_points)")
    ap.add_argument("--dump", action="store_true",
                    help="keep the back-end's inputs (slam_*/dump, without clouds) for --replay")
    ap.add_argument("--replay", metavar="FROM",
                    help="no simulation, no front-end: replay_backend on FROM/<drive>/slam_*/dump "
                         "(a matrix run with --dump) with --set, evaluated as usual (seconds per drive)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="with --replay: a graph_backend parameter for both runs (replay_backend --set)")
    ap.add_argument("--force", action="store_true", help="run drives again even if they have a result.json")
    ap.add_argument("--retry-failed", action="store_true", help="run drives again whose stored status is not ok")
    ap.add_argument("--step-timeout", type=float, default=None, metavar="S",
                    help="stop a step after S seconds (default: no limit)")
    ap.add_argument("--list", action="store_true", help="print the drives and the time estimate; run nothing")
    ap.add_argument("--no-run", action="store_true", help="only the table of the drives already finished")
    c = ap.add_argument_group("check (--check: exit 1 if a drive violates a limit or did not finish)")
    c.add_argument("--check", action="store_true")
    c.add_argument("--max-ate-ratio", type=float, metavar="R", help="ATE with OSM / ATE without")
    c.add_argument("--max-rpe-ratio", type=float, metavar="R", help="t-RPE with OSM / t-RPE without")
    c.add_argument("--min-coverage", type=float, metavar="F", help="fraction of the drive's time estimated")
    c.add_argument("--max-false-loops", type=int, metavar="N")
    c.add_argument("--max-building-error", type=float, metavar="M", help="corrected mean corner error [m]")
    return ap


def main(argv=None, log=print_flushed):
    args = build_parser().parse_args(argv)
    try:
        return _main(args, log)
    except MatrixError as e:
        print("slam_matrix: %s" % e, file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\nslam_matrix: interrupted; finished drives keep their result.json (run the same "
              "command to resume)", file=sys.stderr)
        return 130


def _main(args, log):
    if args.jobs < 1:
        raise MatrixError("--jobs must be at least 1")
    if not args.preset and not any([args.world, args.osm, args.seed, args.length, args.prior_model,
                                    args.sensor, args.gnss, args.manoeuvres, args.drop_scans,
                                    args.dropout_burst, args.map_shift]):
        raise MatrixError("give --preset quick|default|stress or the axes (--world, --seed, --length, ...)")
    drives = build_grid(*axes_from_args(args))
    try:
        sim_args = shlex.split(args.sim_args)
    except ValueError as e:
        raise MatrixError("--sim-args: %s" % e) from None
    out = os.path.abspath(args.out)

    if args.list:
        for i, d in enumerate(drives, 1):
            log("%3d %-60s %5.0f scans  %4.1f min  simulate_urban %s" % (
                i, d.name, d.estimated_scans(), d.estimated_seconds() / 60, " ".join(d.sim_flags() + sim_args)))
        log(estimate_text(drives, args.jobs))
        return 0

    problem = unwritable(out)
    if problem:
        raise MatrixError("cannot write the output folder %s: %s" % (out, problem))

    to_run, stored = plan(drives, out, args.force, args.retry_failed)
    if args.no_run:
        to_run = []
    log("[matrix] %s; %d finished before, %d to run -> %s" % (estimate_text(drives, args.jobs),
                                                              len(stored), len(to_run), out))
    results = {}
    if to_run:
        runnable = [d for d in to_run if not world_problem(d)]
        if runnable:
            tools = ("replay_backend", "evaluate_slam") if args.replay else TOOLS
            missing = [t for t in tools if not os.access(os.path.join(args.bin, t), os.X_OK)]
            if missing:
                raise MatrixError("%s missing in %s: build first (scripts/setup.sh) or give --bin"
                                  % (", ".join(missing), args.bin))
            if not os.path.isfile(args.config):
                raise MatrixError("offline_slam config %s missing" % args.config)
        ctx = Context(os.path.abspath(args.bin), os.path.abspath(args.config), out, sim_args, args.keep,
                      args.step_timeout, evaluate_options(args.bin) if runnable else (), args.dump,
                      os.path.abspath(args.replay) if args.replay else None, args.set)
        results = run_matrix(drives, ctx, to_run, args.jobs, log=log)

    rows = []
    for d in drives:
        row = results.get(d) or stored.get(d)
        if row is None:
            row = drive_row(d, "not run" if args.no_run else "interrupted")
        rows.append(row)
    summary = summarize(rows)
    worst, why = worst_drive(rows)
    log("")
    log(format_table(rows, summary))
    log("")
    failed = [r for r in rows if not is_ok(r)]
    log("[matrix] %d drives, %d ok, %d not ok; median and worst over the ok drives "
        "(worst = max, except cover/recall/sc/s = min)" % (len(rows), len(rows) - len(failed), len(failed)))
    if worst:
        log("[matrix] worst drive: %s: %s" % (worst, why))
    if failed:
        log("[matrix] not ok (status column; logs in <drive>/logs): %s" % ", ".join(r["drive"] for r in failed))
    doc = {
        "generated": time.strftime("%Y-%m-%d %H:%M:%S"),
        "command": sys.argv,
        "preset": args.preset,
        "sim_args": sim_args,
        "baseline_label": BASELINE_LABEL,
        "drives": rows,
        "summary": summary,
        "worst_drive": {"drive": worst, "why": why},
    }
    limits = {a: getattr(args, a) for a, _, _, _ in LIMITS}
    violations = check_rows(rows, limits) if args.check else []
    if args.check:
        doc["check"] = {"limits": limits, "violations": violations}
    try:
        write_atomically(os.path.join(out, "matrix.json"), json.dumps(doc, indent=2) + "\n")
        log("[matrix] rows in %s; each drive's logs in %s/<drive>/logs" % (os.path.join(out, "matrix.json"), out))
    except OSError as e:
        log("[matrix] cannot write %s: %s" % (os.path.join(out, "matrix.json"), e.strerror or e))
    if args.check:
        if not any(v is not None for v in limits.values()):
            log("[matrix] check: no limit given (--max-ate-ratio, --max-rpe-ratio, --min-coverage, "
                "--max-false-loops, --max-building-error); only failed drives count")
            violations = ["%s: did not finish (%s)" % (r["drive"], r["status"]) for r in failed]
        for v in violations:
            log("[matrix] CHECK FAILED: %s" % v)
        if violations:
            return 1
        log("[matrix] check passed (%d drives)" % len(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())

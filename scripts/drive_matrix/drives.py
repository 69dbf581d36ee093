"""One drive of the matrix: its world, the simulate_urban axes, the folder name, the simulator's
flags and the time estimate. Bad input for the whole matrix raises MatrixError."""
import collections
import os
import re

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
KARLSRUHE = "../shared/data/osm/2011_09_26_drive_0005_sync.osm"  # relative to the repo

# simulate_urban's axes. A value equal to SIM_DEFAULTS is passed by omitting its flag, so a drive
# with default values runs on a simulator that does not know the flag yet.
PRIOR_MODELS = ("independent", "blocks", "global", "mixed")
SENSORS = ("hdl64e", "os1_64")
# noisy: the simulator's consumer-grade errors; rtk: exact; canyon: fixes from the satellites the
# buildings let through (NLOS reflections); origin: noisy fixes, but every SLAM run uses only the
# first (GNSS-denied after the start, as a tunnel or the real drive 0005).
GNSS_MODES = ("noisy", "rtk", "canyon", "origin")
# offline_slam / replay_backend: the first fix is the map origin, no GNSS prior after it.
NO_GNSS = ("--gnss", "origin")
SIM_DEFAULTS = {
    "prior_model": "independent",
    "sensor": "hdl64e",
    "gnss": "noisy",
    "manoeuvres": "none",
    "drop_scans": 0.0,
    "dropout_burst": 0,  # N or "N@T": one burst of N consecutive missing scans (at T s)
    "map_shift": 0.0,  # [m] the 'global' prior model's common shift, fixed (0: uniform in 1-3 m)
}

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
SLAM_SCANS_PER_S = 19.0  # each SLAM run (slam_runs(): three, two on an 'origin' drive)
DRIVE_OVERHEAD_S = 8.0


class SlamRun(collections.namedtuple("SlamRun", "name with_osm flags")):
    """One offline_slam (or replay_backend) run of a drive: its folder, whether it has the OSM
    prior (--osm PRIOR, else --no-osm) and its further flags."""

    @property
    def title(self):
        """The step's name in a status: 'offline_slam (with OSM)', 'offline_slam --no-osm', ..."""
        return " ".join((["(with OSM)"] if self.with_osm else ["--no-osm"]) + list(self.flags))

    @property
    def suffix(self):
        """slam_osm -> 'osm': the run's log (offline_slam_osm.log) and step time key."""
        return self.name[len("slam_"):]


class MatrixError(Exception):
    """Bad input for the whole matrix (printed as one line, exit status 2)."""


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
        flags += self.gnss_flags()
        if self.manoeuvres != SIM_DEFAULTS["manoeuvres"]:
            flags += ["--manoeuvres", self.manoeuvres]
        if self.drop_scans > 0:
            flags += ["--drop-scans", fmt_num(self.drop_scans)]
        if self.dropout_burst != SIM_DEFAULTS["dropout_burst"]:
            flags += ["--dropout-burst", str(self.dropout_burst)]
        if self.map_shift > 0:
            flags += ["--prior-global-offset", "%s,%s" % (fmt_num(self.map_shift), fmt_num(self.map_shift))]
        return flags

    def gnss_flags(self):
        """simulate_urban's GNSS flags. The canyon model needs canyons: on the procedural city
        'canyon' and 'origin' drive through its downtown of towers (--downtown; an OSM world has
        its own buildings), so that the two modes share their streets."""
        flags = {"rtk": ["--rtk"], "canyon": ["--gnss-model", "canyon"]}.get(self.gnss, [])
        if self.gnss in ("canyon", "origin") and self.world.path is None:
            flags.append("--downtown")
        return flags

    def slam_runs(self):
        """The drive's SLAM runs (folder, with the OSM prior, flags beside --osm/--no-osm): with
        OSM, the GNSS baseline without it, and odometry + loops (slam_odom: no GNSS after the
        first fix, no OSM). An 'origin' drive has no GNSS after the first fix in any run, so its
        run without OSM is odometry + loops already: slam_odom would repeat it and is not run."""
        if self.gnss == "origin":
            return [SlamRun("slam_osm", True, NO_GNSS), SlamRun("slam_no_osm", False, NO_GNSS)]
        return [SlamRun("slam_osm", True, ()), SlamRun("slam_no_osm", False, ()),
                SlamRun("slam_odom", False, NO_GNSS)]

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
        """Wall time with both cores: simulate, the offline_slam runs, evaluate."""
        scans = self.estimated_scans()
        return scans / SIM_SCANS_PER_S + len(self.slam_runs()) * scans / SLAM_SCANS_PER_S + DRIVE_OVERHEAD_S


BURST = re.compile(r"^(\d+)(@\d+(\.\d*)?)?$")


def parse_burst(value):
    """simulate_urban --dropout-burst N[@T]: N (int) or 'N@T'; 0 = no burst."""
    text = str(value).strip()
    m = BURST.match(text)
    if not m:
        raise MatrixError("--dropout-burst takes N or N@T (scans, seconds), not '%s'" % text)
    return int(text) if not m.group(2) else text

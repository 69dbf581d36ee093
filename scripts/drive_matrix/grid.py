"""The matrix's drives: the presets (default, quick, gnss, stress), the grid designs ('product' and
'rotation') and the axes given on the command line, which replace the preset's."""
import itertools

from .drives import (GNSS_MODES, PRIOR_MODELS, REPO, SENSORS, SIM_DEFAULTS, Drive, MatrixError, World,
                     parse_burst, parse_world)


def preset(**fields):
    """A matrix's axes and design: the simulator's default for every axis not given (the value
    that runs on a simulator without the axis' flag), one world (the city), seed 1, 300 m, and
    the product of the axes."""
    axes = {"worlds": ["city"], "seeds": [1], "lengths": [300], "prior_models": [SIM_DEFAULTS["prior_model"]],
            "sensors": [SIM_DEFAULTS["sensor"]], "gnss": [SIM_DEFAULTS["gnss"]],
            "manoeuvres": [SIM_DEFAULTS["manoeuvres"]], "drop_scans": [SIM_DEFAULTS["drop_scans"]],
            "dropout_burst": [SIM_DEFAULTS["dropout_burst"]], "map_shifts": [SIM_DEFAULTS["map_shift"]],
            "design": "product"}
    axes.update(fields)
    return axes


# Where GNSS fails (doc/matrix.md, "GNSS modes"): per world an urban-canyon and a GNSS-denied
# drive of seeds 1-3, 300 m (on the procedural city with its downtown, seeds 1 and 2 spend 25 %
# and 64 % of their route in it, seed 3 none); independent/hdl64e, so that canyon and origin of
# one seed share route and map.
WHERE_GNSS_FAILS = [{"seed": s, "length": 300, "gnss": g} for g in ("canyon", "origin") for s in (1, 2, 3)]
BOTH_WORLDS = ["karlsruhe", "city"]

PRESETS = {
    # 2 worlds x 3 seeds x {300 m: 3 drives, 1500 m: 1 drive} = 24 drives, GNSS noisy. The (prior
    # model, sensor) pairs rotate so that each appears with both worlds and both lengths.
    "default": preset(
        worlds=BOTH_WORLDS, seeds=[1, 2, 3], lengths=[300, 1500], prior_models=list(PRIOR_MODELS),
        sensors=list(SENSORS), design="rotation", per_cell_short=3, per_cell_long=1,
        # + per world 2 drives whose map is shifted by 1.5 m as a whole: seed 1's first fix is
        # good (0.7 m off), so a map that pulls the trajectory shows as a loss (doc/matrix.md);
        # the canyon and origin drives; and 2 RTK drives (seeds 2 and 3), whose noisy twins (the
        # same drives with consumer-grade fixes) are among the 24.
        extra_drives=[{"seed": s, "length": 300, "prior_model": "global", "map_shift": 1.5} for s in (1, 4)]
        + WHERE_GNSS_FAILS + [{"seed": s, "length": 300, "prior_model": p, "gnss": "rtk"}
                              for s, p in ((2, "blocks"), (3, "independent"))]),
    # 2 worlds x 2 (prior model, sensor) pairs, 200 m: 4 drives, estimated 10 minutes.
    "quick": preset(worlds=BOTH_WORLDS, lengths=[200], prior_models=["independent", "global"],
                    sensors=list(SENSORS), design="rotation", per_cell_short=2, per_cell_long=2),
    # The new GNSS modes alone, for iterating on them: the default's canyon and origin drives
    # (12; --gnss canyon or --gnss origin selects one mode) and, per world, noisy controls of
    # seeds 1 and 3 (their routes and maps; on the city without its downtown).
    "gnss": preset(worlds=BOTH_WORLDS, seeds=[1, 2, 3], gnss=["canyon", "origin"],
                   extra_drives=[{"seed": s, "length": 300} for s in (1, 3)]),
    # The front-end under manoeuvres and missing scans: per world the plain drive (the control),
    # each stressor alone, and all of them together; 300 m requested (manoeuvres 'all' make the
    # route 1.0-1.6 km): 10 drives.
    "stress": preset(
        worlds=BOTH_WORLDS,
        scenarios=[
            {},
            {"drop_scans": 0.05},
            {"dropout_burst": 20},
            {"manoeuvres": "all"},
            {"manoeuvres": "all", "drop_scans": 0.05, "dropout_burst": 20},
        ]),
}
LONG_DRIVE_M = 1000  # rotation design: drives of at least this length get per_cell_long pairs
AXES = ("worlds", "seeds", "lengths", "prior_models", "sensors", "gnss", "manoeuvres",
        "drop_scans", "dropout_burst", "map_shifts")
ROTATED = ("prior_models", "sensors")  # the rotation design's rotated axes


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
        axes = {a: list(v) for a, v in preset().items() if a in AXES}
        axes["worlds"] = [World("city")]
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

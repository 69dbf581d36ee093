"""The printed table, its median and worst rows, the worst drive and --check's limits."""
import statistics

from .drives import SIM_DEFAULTS, fmt_num
from .evaluation import baseline_label, number_or_none


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
    ("fix_rms", "fixRMS", 6, f2, "max"),
    # the three runs (odometry + loops, the GNSS baseline, everything) and OSM's change against both
    ("ate_odom", "ATE_odo", 7, f3, "max"),
    ("ate_no_osm", "ATE_gns", 7, f3, "max"),
    ("ate_osm", "ATE_osm", 7, f3, "max"),
    ("ate_change_pct", "chgGns%", 7, fpct, "max"),
    ("ate_change_odom_pct", "chgOdo%", 7, fpct, "max"),
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


def column_stats(rows, key, direction):
    """{"median", "worst", "worst_drive", "count"} of one metric over the rows with status ok;
    worst in the bad direction ("max", "min"; None: no worst)."""
    vals = [(r["metrics"][key], r["drive"]) for r in rows
            if is_ok(r) and number_or_none((r.get("metrics") or {}).get(key)) is not None]
    entry = {"median": None, "worst": None, "worst_drive": None, "count": len(vals)}
    if vals:
        entry["median"] = statistics.median(v for v, _ in vals)
        if direction:
            pick = max if direction == "max" else min
            v, d = pick(vals, key=lambda x: x[0])
            entry["worst"], entry["worst_drive"] = v, d
    return entry


def summarize(rows):
    """{metric: {"median", "worst", "worst_drive", "count"}} over the rows with status ok."""
    return {key: column_stats(rows, key, direction) for key, _, _, _, direction in COLUMNS}


def worst_drive(rows):
    """(drive, why) of the finished drive whose OSM run did worst against its run without OSM
    (the GNSS baseline; odometry + loops on an 'origin' drive): the largest ATE change. Drives
    that did not finish are listed apart."""
    scored = [r for r in rows if is_ok(r)
              and number_or_none((r.get("metrics") or {}).get("ate_change_pct")) is not None]
    if not scored:
        return None, None
    r = max(scored, key=lambda r: r["metrics"]["ate_change_pct"])
    return r["drive"], "ATE change %+.1f %% vs %s (ATE %.3f m with OSM, %.3f m without)" % (
        r["metrics"]["ate_change_pct"], baseline_label(r.get("gnss")), r["metrics"].get("ate_osm") or 0.0,
        r["metrics"].get("ate_no_osm") or 0.0)


AXIS_COLUMNS = [("#", 3), ("world", 10), ("seed", 4), ("len", 5), ("prior", 11), ("sensor", 6),
                ("gnss", 6)]


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
                 cut(str(r.get("sensor", "?")), 6).ljust(6), cut(str(r.get("gnss", "?")), 6).ljust(6)]
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

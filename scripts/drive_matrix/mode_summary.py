"""The summary per GNSS mode: the OSM prior's value depends on what else holds the trajectory,
so each mode is judged against the baseline a user would otherwise have (odometry + loops on
'origin' drives, the GNSS baseline on the others). Over each mode's finished drives: the median
and the worst drive of the OSM run's ATE and of its change against that baseline, and the
buildings: the shape error S_shp and the absolute corner error S_corr against the bound B_bnd."""
from .drives import GNSS_MODES
from .evaluation import baseline_label, ratio
from .table import column_stats, is_ok


def change_key(mode):
    """The row's ATE change against the mode's baseline."""
    return "ate_change_odom_pct" if mode == "origin" else "ate_change_pct"


def summarize_modes(rows):
    """{mode: {"drives", "baseline", "ate_osm", "ate_change_pct", "seen_shape", "seen_corrected",
    "offset_bound" (each column_stats()), "corner_error_over_bound"}} for each mode with a
    finished drive. corner_error_over_bound: median S_corr / median B_bnd (a ratio of medians:
    a drive's own B_bnd can be 0)."""
    modes = list(GNSS_MODES) + sorted({str(r.get("gnss")) for r in rows} - set(GNSS_MODES))
    out = {}
    for mode in modes:
        mine = [r for r in rows if is_ok(r) and str(r.get("gnss")) == mode]
        if not mine:
            continue
        s = {"drives": len(mine), "baseline": baseline_label(mode),
             "ate_osm": column_stats(mine, "ate_osm", "max"),
             "ate_change_pct": column_stats(mine, change_key(mode), "max")}
        for key in ("seen_shape", "seen_corrected", "offset_bound"):
            s[key] = column_stats(mine, key, "max")
        s["corner_error_over_bound"] = ratio(s["seen_corrected"]["median"], s["offset_bound"]["median"])
        out[mode] = s
    return out


def _num(x, fmt):
    return "-" if x is None else fmt % x


def _median_and_worst(entry, fmt, unit):
    text = "median %s%s" % (_num(entry["median"], fmt), unit)
    if entry["worst_drive"]:
        text += ", worst %s%s (%s)" % (_num(entry["worst"], fmt), unit, entry["worst_drive"])
    return text


def format_mode_summary(summary):
    """One line per mode, e.g. '[matrix] canyon, 6 drives: ATE with OSM median 0.812 m, worst ...;
    vs gnss median -31.2 %, worst +1.5 % (...); S_shp median 0.14 m; S_corr median 0.91 m =
    1.10 x B_bnd median 0.83 m'."""
    lines = []
    for mode, s in summary.items():
        lines.append("[matrix] %s, %d drives: ATE with OSM %s; vs %s %s; S_shp median %s m; S_corr median %s m = "
                     "%s x B_bnd median %s m" % (
                         mode, s["drives"], _median_and_worst(s["ate_osm"], "%.3f", " m"), s["baseline"],
                         _median_and_worst(s["ate_change_pct"], "%+.1f", " %"),
                         _num(s["seen_shape"]["median"], "%.2f"), _num(s["seen_corrected"]["median"], "%.2f"),
                         _num(s["corner_error_over_bound"], "%.2f"), _num(s["offset_bound"]["median"], "%.2f")))
    return lines

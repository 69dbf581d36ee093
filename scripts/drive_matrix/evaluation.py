"""One row's numbers from the tools' JSON files (evaluate_slam --json, offline_slam's
timing.json, simulate_urban's sim_info.json). Older tools lack keys: every missing number is None
(shown as '-'), never an exception."""
import math

# evaluate_slam --baseline-label of the run without OSM (slam_no_osm): the GNSS baseline, what a
# user has without the OSM prior; on an 'origin' drive it has no GNSS after the first fix, so it
# is odometry + loops.
GNSS_LABEL = "gnss"
ODOM_LABEL = "odom+loops"


def baseline_label(gnss_mode):
    return ODOM_LABEL if gnss_mode == "origin" else GNSS_LABEL


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


def baseline_block(evaluation, label=GNSS_LABEL):
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
    m.update(fix_metrics(sim))
    return m


# The fixes' errors over the drive, as simulate_urban measured them (sim_info.json "gnss_ins";
# the canyon model adds the 95 % error, the NLOS share and the reported accuracy).
FIX_KEYS = {"fix_rms": "gnss_error_rms_m", "fix_p95": "gnss_error_p95_m", "fix_max": "gnss_error_max_m",
            "fix_nlos_share": "nlos_fix_share", "fix_outage_s": "outage_s",
            "fix_reported_mean": "reported_accuracy_mean_m", "fix_true_mean": "gnss_error_mean_m"}


def fix_metrics(sim_info):
    gnss = dig(sim_info, "gnss_ins")
    gnss = gnss if isinstance(gnss, dict) else {}
    m = {key: number_or_none(gnss.get(name)) for key, name in FIX_KEYS.items()}
    first = gnss.get("first_fix_error_enu_m")  # the map origin's error: all an 'origin' run has
    ok = isinstance(first, list) and len(first) >= 2 and all(number_or_none(v) is not None for v in first[:2])
    m["first_fix_error"] = math.hypot(first[0], first[1]) if ok else None
    return m


def odometry_metrics(m, evaluation_odom, gnss_mode):
    """The odometry + loops run's ATE and t-RPE, and the OSM run's ATE change against it [%],
    beside parse_metrics' m. On an 'origin' drive the run without OSM is that run (no GNSS
    after the first fix in either): its numbers, as one run measured them. Missing: None."""
    if gnss_mode == "origin":
        ate, rpe, run = m.get("ate_no_osm"), m.get("rpe_no_osm"), "slam_no_osm"
    else:
        ate = number_or_none(dig(evaluation_odom, "slam", "ate_m", "mean"))
        rpe = number_or_none(dig(evaluation_odom, "slam", "rpe_trans_m", "mean"))
        run = "slam_odom" if ate is not None else None
    r = ratio(m.get("ate_osm"), ate)
    return {"ate_odom": ate, "rpe_odom": rpe, "ate_change_odom_pct": None if r is None else 100.0 * (r - 1.0),
            "odom_run": run, "baseline": baseline_label(gnss_mode)}

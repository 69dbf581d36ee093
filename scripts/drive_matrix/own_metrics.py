"""The numbers the matrix measures itself from the runs' files, beyond evaluate_slam's: coverage
(when evaluate_slam has none), heading and raw odometry tilt, and the absolute offset bound of
the map against the GNSS fixes."""
import math
import os

from .files import read_json, sorted_listdir


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
    odometry's tilt from every trajectory metric, so the matrix shows it apart (doc/matrix.md:
    63 deg on a drive whose trajectory tilt was 0.04 deg)."""
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


def gnss_mean_error(drive_dir, first_only=False):
    """Mean horizontal (east, north) error [m] of the drive's fixes against oxts_true (the
    simulator's truth), over the records with a fix (first_only: the first of them); None
    without them."""
    data = os.path.join(drive_dir, "oxts", "data")
    east = north = 0.0
    n = 0
    for name in sorted_listdir(data):
        fix = _oxts_latlon(os.path.join(data, name))
        true = _oxts_latlon(os.path.join(drive_dir, "oxts_true", "data", name))
        if fix is None or true is None:
            continue
        r = 6378137.0 * math.pi / 180.0
        east += (fix[1] - true[1]) * r * math.cos(math.radians(true[0]))
        north += (fix[0] - true[0]) * r
        n += 1
        if first_only:
            break
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


def absolute_offset_metrics(sim_dir, drive_dir, corrected_geojson, first_fix_only=False):
    """Simulated drives only: the fixes' mean error, the observed buildings' mean prior offset
    and offset_bound() of the two ("B_bnd": no estimator's buildings or trajectory end closer
    in the mean). first_fix_only: the runs had no fix but the first (an 'origin' drive), so
    that one is their only absolute reference beside the map."""
    m = {"gnss_mean_error": None, "map_mean_offset": None, "offset_bound": None}
    b = gnss_mean_error(drive_dir, first_fix_only)
    seen = observed_prior_offset(sim_dir, corrected_geojson)
    if b is not None:
        m["gnss_mean_error"] = math.hypot(*b)
    if seen is not None:
        m["map_mean_offset"] = math.hypot(*seen[0])
    if b is not None and seen is not None:
        m["offset_bound"] = offset_bound(seen[0], b)
    return m

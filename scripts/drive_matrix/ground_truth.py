"""The true pose of every scan in offline_slam's map frame (ENU at the first OXTS fix), so that
coverage can see where the estimate stops short: simulate_urban's truth is in ENU at its own
origin, and offline_slam's own truth file has only the keyframes."""
import calendar
import json
import math
import os
import re

from .files import sorted_listdir, write_atomically


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


def write_full_ground_truth(sim_dir, drive_dir, out_path, map_origin=None):
    """The true base_link pose of every scan (TUM) in offline_slam's map frame, ENU at the
    first OXTS fix (or at map_origin, (lat, lon, alt): a merged map's): simulate_urban's
    ground_truth/poses_imu.txt (ENU at sim_info's origin) moved through ECEF. offline_slam's own
    ground_truth_tum.txt has only the estimate's keyframes, so it cannot show a gap in the
    estimate; this one has the whole drive. Returns the pose count."""
    with open(os.path.join(sim_dir, "sim_info.json")) as f:
        origin = json.load(f)["enu_origin"]
    first = map_origin or first_fix(drive_dir)
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
    for name in sorted_listdir(folder):
        try:
            with open(os.path.join(folder, name)) as f:
                v = [float(x) for x in f.read().split()]
        except (OSError, ValueError):
            return None
        if len(v) >= 3 and all(math.isfinite(x) for x in v[:3]) and not (len(v) > 23 and v[23] >= NO_FIX_ACCURACY):
            return v[0], v[1], v[2]
    return None

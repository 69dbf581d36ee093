"""Consensus of a simulated fleet (issue 53's targets): the first N drives of a fleet_map.py run
merged for each N, and each merged map scored against the simulator's truth:

- the observed buildings' mean corner error and shape error (evaluate_slam, as the matrix does);
- every drive's ATE in the merged map against its ATE alone (the same drive's offline_slam run);
- the inter-session loops: false ones (their relative pose against the truth) and the recall of
  cross-drive revisits (a keyframe whose true position is within REVISIT_RADIUS of an earlier
  drive's keyframe is a revisit; it is found when it has an inter-session loop).

Needs the fleet's drive folders (drives/<name>/sim with the truth, drives/<name>/slam)."""
import bisect
import json
import math
import os
import subprocess

from drive_matrix.ground_truth import write_full_ground_truth

REVISIT_RADIUS = 5.0  # [m] issue 53: ground-truth positions within 5 m
FALSE_LOOP_TRANSLATION = 1.0  # [m] a loop further than this from the truth is false
FALSE_LOOP_YAW = math.radians(2.0)


class ConsensusError(Exception):
    """The fleet folder lacks what the evaluation needs."""


def fleet_drives(fleet_dir):
    """(name, sim folder, KITTI drive folder, dump folder, alone run folder) of every finished
    simulated drive, in route-seed order (sim_w<W>_s<S>)."""
    drives_dir = os.path.join(fleet_dir, "drives")
    if not os.path.isdir(drives_dir):
        raise ConsensusError("%s has no drives/ folder (not a fleet_map.py output)" % fleet_dir)
    found = []
    for name in os.listdir(drives_dir):
        d = os.path.join(drives_dir, name)
        sim, slam = os.path.join(d, "sim"), os.path.join(d, "slam")
        if not (os.path.isfile(os.path.join(d, "done.json")) and os.path.isdir(sim)):
            continue
        drive_dir = _kitti_drive(sim)
        if drive_dir:
            found.append((_seed_of(name), name, sim, drive_dir, os.path.join(slam, "dump"), slam))
    return [f[1:] for f in sorted(found)]


def _seed_of(name):
    tail = name.rsplit("_s", 1)[-1]
    return int(tail) if tail.isdigit() else 1 << 30


def _kitti_drive(sim):
    for date in sorted(os.listdir(sim)):
        d = os.path.join(sim, date)
        if os.path.isdir(d):
            for sub in sorted(os.listdir(d)):
                if sub.endswith("_sync"):
                    return os.path.join(d, sub)
    return None


def read_tum(path):
    """[(stamp, x, y, z, qx, qy, qz, qw)] of a TUM file."""
    rows = []
    with open(path) as f:
        for line in f:
            if line.strip() and not line.startswith("#"):
                rows.append(tuple(float(v) for v in line.split()[:8]))
    return rows


def yaw_of(qx, qy, qz, qw):
    return math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))


class Truth:
    """A drive's true poses (TUM, in the merged map's frame), looked up by stamp."""

    def __init__(self, rows):
        self.rows = rows
        self.stamps = [r[0] for r in rows]

    def at(self, stamp):
        i = bisect.bisect_left(self.stamps, stamp)
        best = min((j for j in (i - 1, i) if 0 <= j < len(self.rows)),
                   key=lambda j: abs(self.stamps[j] - stamp))
        return self.rows[best]


def planar_relative(to_row, from_row):
    """(dx, dy, dyaw) of `from` in `to`'s frame (planar)."""
    ty, fy = yaw_of(*to_row[4:8]), yaw_of(*from_row[4:8])
    dx, dy = from_row[1] - to_row[1], from_row[2] - to_row[2]
    c, s = math.cos(ty), math.sin(ty)
    return c * dx + s * dy, -s * dx + c * dy, math.atan2(math.sin(fy - ty), math.cos(fy - ty))


def judge_loops(loops_csv, truths):
    """(false loops, loops) of merge_sessions' inter_session_loops.csv against the truths."""
    false, total = 0, 0
    with open(loops_csv) as f:
        for line in f:
            if not line.strip() or line.startswith("#"):
                continue
            v = line.split()
            fs, fstamp, ts, tstamp = int(v[0]), float(v[1]), int(v[2]), float(v[3])
            x, y = float(v[4]), float(v[5])
            yaw = yaw_of(*(float(q) for q in v[7:11]))
            tx, ty, tyaw = planar_relative(truths[ts].at(tstamp), truths[fs].at(fstamp))
            total += 1
            if math.hypot(x - tx, y - ty) > FALSE_LOOP_TRANSLATION or \
                    abs(math.atan2(math.sin(yaw - tyaw), math.cos(yaw - tyaw))) > FALSE_LOOP_YAW:
                false += 1
    return false, total


def revisit_recall(session_keyframes, loops_csv, truths):
    """(found, revisits): keyframes of drive j > 0 whose true position is within REVISIT_RADIUS
    of a keyframe of an earlier drive, and how many of them have an inter-session loop."""
    looped = set()
    with open(loops_csv) as f:
        for line in f:
            if line.strip() and not line.startswith("#"):
                v = line.split()
                looped.add((int(v[0]), round(float(v[1]), 3)))
    positions = {s: [truths[s].at(row[0])[1:3] for row in rows] for s, rows in session_keyframes.items()}
    found = revisits = 0
    earlier = []
    for s in sorted(session_keyframes):
        if earlier:
            for row, p in zip(session_keyframes[s], positions[s]):
                if any(math.hypot(p[0] - q[0], p[1] - q[1]) <= REVISIT_RADIUS for q in earlier):
                    revisits += 1
                    found += (s, round(row[0], 3)) in looped
        earlier.extend(positions[s])
    return found, revisits


def evaluate_slam(bin_dir, args):
    out = subprocess.run([os.path.join(bin_dir, "evaluate_slam")] + args + ["--planar", "--json"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, check=False)
    if out.returncode != 0:
        raise ConsensusError("evaluate_slam %s: %s" % (" ".join(args[:2]), out.stderr.strip()[-300:]))
    return json.loads(out.stdout)


def dump_origin(dump):
    """(lat, lon, alt) of a dump's map frame (origin.txt)."""
    with open(os.path.join(dump, "origin.txt")) as f:
        for line in f:
            if line.strip() and not line.startswith("#"):
                return tuple(float(v) for v in line.split()[:3])
    raise ConsensusError("%s/origin.txt holds no origin" % dump)


def ate_mean(ev):
    """The mean planar ATE of an evaluate_slam --json document (the matrix's ATE)."""
    return ev["slam"]["ate_m"]["mean"]


def merge(bin_dir, config, dumps, out, log_path):
    """merge_sessions over the dumps into out (read back when its summary is there)."""
    summary = os.path.join(out, "summary.json")
    if not os.path.isfile(summary):
        cmd = [os.path.join(bin_dir, "merge_sessions"), "--output", out, "--config", config]
        for d in dumps:
            cmd += ["--session", d]
        with open(log_path, "w") as log:
            rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, check=False).returncode
        if rc not in (0, 3):
            raise ConsensusError("merge_sessions failed (%d): see %s" % (rc, log_path))
    with open(summary) as f:
        return json.load(f)


def evaluate_count(fleet_dir, drives, n, bin_dir, config, folder="consensus"):
    """Merges the first n drives into fleet_dir/folder/n<N> and scores the merged map; a dict
    of the figures."""
    chosen = drives[:n]
    out = os.path.join(fleet_dir, folder, "n%02d" % n)
    os.makedirs(out, exist_ok=True)
    summary = merge(bin_dir, config, [d[3] for d in chosen], os.path.join(out, "merged"),
                    os.path.join(out, "merge_sessions.log"))
    origin = dump_origin(chosen[0][3])  # the merged map's frame: the first session's
    truths, ate_ratio, ate_merged = {}, [], []
    session_rows = {}
    for s, (name, sim, drive_dir, dump, alone) in enumerate(chosen):
        gt_map = os.path.join(out, "truth_%s.txt" % name)
        write_full_ground_truth(sim, drive_dir, gt_map, map_origin=origin)
        gt_own = os.path.join(out, "truth_%s_own.txt" % name)
        write_full_ground_truth(sim, drive_dir, gt_own)
        truths[s] = Truth(read_tum(gt_map))
        merged_traj = os.path.join(out, "merged", "sessions", str(s), "trajectory_tum.txt")
        session_rows[s] = read_tum(merged_traj)
        merged_ate = ate_mean(evaluate_slam(bin_dir, ["--estimate", merged_traj, "--ground-truth", gt_map]))
        alone_ate = ate_mean(evaluate_slam(bin_dir, ["--estimate", os.path.join(alone, "trajectory_tum.txt"),
                                                     "--ground-truth", gt_own]))
        ate_merged.append(merged_ate)
        ate_ratio.append(merged_ate / alone_ate if alone_ate > 0 else float("nan"))
    sim0 = chosen[0][1]
    ev = evaluate_slam(bin_dir, [
        "--estimate", os.path.join(out, "merged", "sessions", "0", "trajectory_tum.txt"),
        "--ground-truth", os.path.join(out, "truth_%s.txt" % chosen[0][0]),
        "--origin", "%.9f,%.9f" % origin[:2],
        "--buildings-true", os.path.join(sim0, "buildings_true.geojson"),
        "--buildings-prior", os.path.join(sim0, "prior.osm"),
        "--buildings-corrected", os.path.join(out, "merged", "buildings_corrected.geojson")])
    loops_csv = os.path.join(out, "merged", "inter_session_loops.csv")
    false, loops = judge_loops(loops_csv, truths)
    found, revisits = revisit_recall(session_rows, loops_csv, truths)
    seen = ev.get("buildings_corrected_observed", {})
    seen_prior = ev.get("buildings_prior_observed", {})
    return {
        "drives": n,
        "observed_buildings": seen.get("matched"),
        "corner_error_m": seen.get("mean_corner_error_m"),
        "shape_error_m": seen.get("mean_corner_error_shape_m"),
        "prior_corner_error_m": seen_prior.get("mean_corner_error_m"),
        "ate_merged_median_m": _median(ate_merged),
        "ate_ratio_median": _median(ate_ratio),
        "ate_ratio_worst": max(ate_ratio),
        "inter_session_loops": loops,
        "false_loops": false,
        "revisits": revisits,
        "revisit_recall": found / revisits if revisits else None,
        "buildings_by_drives": summary.get("buildings_by_drives"),
        "merge_seconds": summary.get("merge_seconds"),
    }


def _median(values):
    v = sorted(values)
    return v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2])


def format_table(rows):
    head = "%6s %9s %10s %9s %9s %10s %10s %10s %7s %6s %8s %8s" % (
        "drives", "observed", "corner m", "shape m", "prior m", "ATE med m", "ATE/alone", "worst",
        "loops", "false", "recall", "merge s")
    lines = [head]
    for r in rows:
        rec = r["revisit_recall"]
        lines.append("%6d %9s %10.3f %9.3f %9.3f %10.3f %10.3f %10.3f %7d %6d %8s %8.1f" % (
            r["drives"], r["observed_buildings"], r["corner_error_m"], r["shape_error_m"],
            r["prior_corner_error_m"], r["ate_merged_median_m"], r["ate_ratio_median"],
            r["ate_ratio_worst"], r["inter_session_loops"], r["false_loops"],
            "-" if rec is None else "%.1f %%" % (100 * rec), r["merge_seconds"]))
    return "\n".join(lines)


def plot(rows, path):
    """Error against the number of drives (matplotlib, no display)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = [r["drives"] for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(n, [r["corner_error_m"] for r in rows], "o-", label="corner error (observed)")
    ax.plot(n, [r["shape_error_m"] for r in rows], "s-", label="shape error")
    ax.plot(n, [r["prior_corner_error_m"] for r in rows], "k--", label="prior")
    ax.set_xscale("log", base=2)
    ax.set_xticks(n)
    ax.set_xticklabels([str(v) for v in n])
    ax.set_xlabel("drives merged")
    ax.set_ylabel("m")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def compare_maps(joint_dir, other_dir):
    """How far a merged map (solved in tiles) is from the joint solve: keyframe positions (by
    stamp, every session) and building reference corners (by id), mean and max [m]."""
    def keyframes(d):
        out = {}
        sessions = os.path.join(d, "sessions")
        for s in os.listdir(sessions):
            for row in read_tum(os.path.join(sessions, s, "trajectory_tum.txt")):
                out[(s, round(row[0], 3))] = row[1:3]
        return out

    def corners(d):
        with open(os.path.join(d, "buildings_corrected.geojson")) as f:
            doc = json.load(f)
        out = {}
        for feature in doc["features"]:
            ring = feature["geometry"]["coordinates"][0]
            props = feature["properties"]
            lon, lat = min(ring, key=lambda p: (p[0], p[1]))[:2]
            # metres per degree near the ring: a local equirectangular projection is exact enough
            out[(props["id"], props.get("part", 0))] = (lat * 111320.0, lon * 111320.0 * math.cos(math.radians(lat)))
        return out

    result = {}
    for name, read in (("keyframes", keyframes), ("buildings", corners)):
        a, b = read(joint_dir), read(other_dir)
        d = [math.hypot(a[k][0] - b[k][0], a[k][1] - b[k][1]) for k in a if k in b]
        result[name] = {"compared": len(d), "mean_m": sum(d) / len(d) if d else None, "max_m": max(d) if d else None}
    return result

#!/usr/bin/python3
"""Soak test (issue 22): the whole ROS system on a looped simulated drive for N minutes.

A simulated drive (simulate_urban + kitti2bag, or --sim-dir) is played with `rosbag play -l
--clock` into launch/sim.launch; every loop is a jump back in time, which the scan matcher answers
by starting a new track (doc/reliability.md). Buildings come from scripts/overpass_test_server.py,
which injects a fault (HTTP 429/504, dropped connections, truncated and malformed answers, ...)
for `--fault-s` out of every `--fault-every-s` seconds. Every `--sample-s` seconds: the nodelet
manager's resident memory and CPU, the scans processed, the keyframes in the graph (slam/path).
At the end `save_map` must succeed with every keyframe of the graph.

The graph keeps every keyframe (and its cloud), so memory grows with keyframes by design. The
verdict is about what is not explained by that: after the warm-up, memory per keyframe added in
the second half of the run must not exceed the first half's by more than --max-growth-ratio
(a leak per scan or per fault grows faster than the keyframes), and no 5-minute window may pass
without a new keyframe (a stall). Exit status 1 when a check fails.

  scripts/soak.sh --minutes 60 [--out DIR] [--sim-dir DIR] [--length M] [--rate R]
                  [--sample-s S] [--warmup-min W] [--fault-every-s S] [--fault-s S]

Only processes started here are stopped (their process groups); the master gets a free port.
Writes OUT/soak.csv (samples), OUT/soak.json (verdict) and OUT/logs/.
"""
import argparse
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FAULTS = ("http429", "http504", "drop", "short_read", "truncate", "malformed", "remark")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Processes:
    """Process groups started here, stopped in reverse order (SIGINT, then harder)."""

    def __init__(self, log_dir):
        self.log_dir = log_dir
        self.started = []

    def start(self, name, cmd, env=None):
        log = open(os.path.join(self.log_dir, name + ".log"), "w")
        p = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env,
                             start_new_session=True)
        self.started.append((name, p))
        return p

    def stop(self, p, timeout=20.0):
        if p.poll() is not None:
            return
        # roslaunch starts its nodes in sessions of their own: remember them before it goes.
        children = child_pids(p.pid)
        os.killpg(p.pid, signal.SIGINT)
        try:
            p.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
        for sig in (signal.SIGTERM, signal.SIGKILL):
            alive = [c for c in children if os.path.exists("/proc/%d" % c)]
            for c in alive:
                os.kill(c, sig)
            if alive:
                time.sleep(2.0)

    def stop_all(self):
        for _, p in reversed(self.started):
            try:
                self.stop(p)
            except ProcessLookupError:
                pass


def child_pids(parent):
    """Direct children of a process (/proc/PID/stat's ppid)."""
    pids = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open("/proc/%s/stat" % entry) as f:
                    if int(f.read().rsplit(")", 1)[1].split()[1]) == parent:
                        pids.append(int(entry))
            except (OSError, ValueError, IndexError):
                pass
    return pids


def cmdline(pid):
    try:
        with open("/proc/%d/cmdline" % pid, "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def rss_mb(pid):
    with open("/proc/%d/status" % pid) as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def cpu_seconds(pid):
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def run(cmd, log):
    with open(log, "w") as f:
        if subprocess.call(cmd, stdout=f, stderr=subprocess.STDOUT) != 0:
            sys.exit("soak: %s failed (log: %s)" % (cmd[0], log))


def prepare_drive(args, bin_dir, logs):
    sim = args.sim_dir or os.path.join(args.out, "sim")
    if not args.sim_dir:
        print("[soak] simulate_urban --length %g -> %s" % (args.length, sim), flush=True)
        run([os.path.join(bin_dir, "simulate_urban"), "--out", sim, "--length", str(args.length)],
            os.path.join(logs, "simulate_urban.log"))
    drives = [os.path.join(dp, d) for dp, dirs, _ in os.walk(sim) for d in dirs
              if "_drive_" in d and d.endswith("_sync")]
    if not drives or not os.path.exists(os.path.join(sim, "prior.osm")):
        sys.exit("soak: %s is not a simulate_urban output" % sim)
    bag = os.path.join(args.out, "drive.bag")
    print("[soak] kitti2bag -> %s" % bag, flush=True)
    run([os.path.join(bin_dir, "kitti2bag"), drives[0], bag], os.path.join(logs, "kitti2bag.log"))
    return bag, os.path.join(sim, "prior.osm")


class Counters:
    def __init__(self):
        self.lock = threading.Lock()
        self.scans = self.failed = self.path_length = self.keyframes_made = 0

    def on_status(self, msg):
        with self.lock:
            self.scans += 1
            self.failed += int(msg.failed)
            self.keyframes_made += int(msg.new_keyframe)

    def on_path(self, msg):
        with self.lock:
            self.path_length = len(msg.poses)


def set_fault(control_url, mode):
    try:
        urllib.request.urlopen(control_url + "?mode=" + mode, timeout=5).read()
    except OSError as e:
        print("[soak] could not set Overpass mode %s: %s" % (mode, e), flush=True)


def slope(xs, ys):
    n = len(xs)
    if n < 2:
        return float("nan")
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else float("nan")


def verdict(samples, args):
    """Memory per keyframe in the two halves after the warm-up, stalls, and the slopes."""
    after = [s for s in samples if s["t_s"] >= 60.0 * args.warmup_min]
    out = {"samples": len(samples), "samples_after_warmup": len(after), "checks": {}}
    if len(after) < 4:
        out["checks"]["enough_samples"] = False
        return out
    t_h = [s["t_s"] / 3600.0 for s in after]
    out["rss_slope_mb_per_h"] = slope(t_h, [s["rss_mb"] for s in after])
    out["keyframes_per_h"] = slope(t_h, [s["keyframes"] for s in after])
    half = len(after) // 2
    per_kf = []
    for part in (after[:half + 1], after[half:]):
        dk = part[-1]["keyframes"] - part[0]["keyframes"]
        dm = part[-1]["rss_mb"] - part[0]["rss_mb"]
        per_kf.append(1024.0 * dm / dk if dk > 0 else float("nan"))
    out["kb_per_keyframe_first_half"], out["kb_per_keyframe_second_half"] = per_kf
    first = max(per_kf[0], 1.0)  # memory that stayed flat is no baseline for a ratio
    out["checks"]["memory_per_keyframe"] = per_kf[1] <= args.max_growth_ratio * first
    # A stall: a 5-minute window (or the whole run, if shorter) without a new keyframe.
    window = min(300.0, samples[-1]["t_s"] / 2)
    stalls = 0
    for s in samples:
        later = [x for x in samples if s["t_s"] + window <= x["t_s"]]
        if later and later[0]["keyframes"] <= s["keyframes"]:
            stalls += 1
    out["stall_windows"] = stalls
    out["checks"]["no_stall"] = stalls == 0
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--out", default=os.path.join(ROOT, "build_ws", "soak"))
    ap.add_argument("--sim-dir", help="an earlier simulate_urban output (else one is simulated)")
    ap.add_argument("--length", type=float, default=300.0, help="[m] of the simulated drive")
    ap.add_argument("--rate", type=float, default=1.0, help="rosbag play rate")
    ap.add_argument("--sample-s", type=float, default=10.0)
    ap.add_argument("--warmup-min", type=float, default=10.0)
    ap.add_argument("--fault-every-s", type=float, default=120.0)
    ap.add_argument("--fault-s", type=float, default=30.0)
    ap.add_argument("--max-growth-ratio", type=float, default=1.5,
                    help="memory per keyframe, second half over first half")
    args = ap.parse_args()
    args.out = os.path.abspath(args.out)
    logs = os.path.join(args.out, "logs")
    os.makedirs(logs, exist_ok=True)
    bin_dir = os.path.join(ROOT, "build_ws", "devel", "lib", "osm_graph_slam")
    bag, prior = prepare_drive(args, bin_dir, logs)

    env = dict(os.environ)
    env["ROS_MASTER_URI"] = "http://127.0.0.1:%d" % free_port()
    env["ROS_HOME"] = os.path.join(args.out, "ros_home")
    os.environ.update(env)
    procs = Processes(logs)
    stop = threading.Event()

    def on_signal(signum, _frame):
        # Ctrl-C or SIGTERM: end the drive early, still save and judge, and stop every process
        # this script started (they run in sessions of their own and would outlive it).
        if stop.is_set():
            raise SystemExit("soak: second signal, stopping now")
        print("[soak] signal %d: stopping early, then save_map and the verdict" % signum,
              flush=True)
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        procs.start("roscore", ["roscore", "-p", env["ROS_MASTER_URI"].rsplit(":", 1)[1]], env)
        port_file = os.path.join(args.out, ".overpass_port")
        if os.path.exists(port_file):
            os.remove(port_file)
        procs.start("overpass", [sys.executable, os.path.join(ROOT, "scripts",
                                 "overpass_test_server.py"), "--osm", prior, "--port", "0",
                                 "--port-file", port_file], env)
        deadline = time.monotonic() + 30
        while not os.path.exists(port_file) and time.monotonic() < deadline:
            time.sleep(0.2)
        overpass = "http://127.0.0.1:%s" % open(port_file).read().strip()
        launch = procs.start("roslaunch", [
            "roslaunch", "--wait", "osm_graph_slam", "sim.launch", "osm_source:=overpass",
            "overpass_url:=%s/api/interpreter" % overpass, "osm_file:=" + prior,
            "use_sim_time:=true", "rviz:=false", "output:=log"], env)

        import rospy
        import rosgraph

        sys.path.insert(0, os.path.join(ROOT, "scripts"))
        from demo_ros import decoded  # messages without generated Python modules

        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            try:
                services = [s for s, _ in rosgraph.Master("/soak").getSystemState()[2]]
                if "/graph_backend/save_map" in services:
                    break
            except Exception:
                pass
            if launch.poll() is not None:
                sys.exit("soak: roslaunch exited (logs/roslaunch.log)")
            time.sleep(0.5)
        else:
            sys.exit("soak: the nodelets did not come up in 120 s (logs/roslaunch.log)")
        time.sleep(3.0)  # tf_static and the subscriptions settle
        manager = [p for p in child_pids(launch.pid) if "nodelet manager" in cmdline(p)]
        if not manager:
            sys.exit("soak: no nodelet manager among roslaunch's processes")
        manager = manager[0]

        rospy.init_node("soak_monitor", anonymous=True, disable_signals=True)
        c = Counters()
        rospy.Subscriber("/scan_matching_status", rospy.AnyMsg, decoded(c.on_status),
                         queue_size=1000)
        rospy.Subscriber("/slam/path", rospy.AnyMsg, decoded(c.on_path), queue_size=2)
        play = procs.start("rosbag_play", ["rosbag", "play", "--clock", "-q", "-l", "-r",
                                           str(args.rate), bag], env)
        print("[soak] %.0f min: manager pid %d, Overpass %s, playing %s in a loop"
              % (args.minutes, manager, overpass, os.path.basename(bag)), flush=True)

        samples, t0 = [], time.monotonic()
        cpu0, fault_index, fault_on = cpu_seconds(manager), 0, False
        csv = open(os.path.join(args.out, "soak.csv"), "w")
        csv.write("t_s,rss_mb,cpu_percent,scans,failed,keyframes,overpass_mode\n")
        last_cpu, last_t = cpu0, 0.0
        mode = "normal"
        while time.monotonic() - t0 < 60.0 * args.minutes and not stop.is_set():
            if stop.wait(args.sample_s):
                break
            t = time.monotonic() - t0
            if launch.poll() is not None or not os.path.exists("/proc/%d" % manager):
                print("[soak] the nodelet manager is gone at %.0f s" % t, flush=True)
                break
            phase = t % args.fault_every_s
            want_fault = args.fault_every_s - args.fault_s <= phase
            if want_fault != fault_on:
                fault_on = want_fault
                mode = FAULTS[fault_index % len(FAULTS)] if fault_on else "normal"
                fault_index += fault_on
                set_fault(overpass + "/control", mode)
            cpu = cpu_seconds(manager)
            with c.lock:
                s = {"t_s": t, "rss_mb": rss_mb(manager),
                     "cpu_percent": 100.0 * (cpu - last_cpu) / max(t - last_t, 1e-6),
                     "scans": c.scans, "failed": c.failed, "keyframes": c.path_length,
                     "overpass_mode": mode}
            last_cpu, last_t = cpu, t
            samples.append(s)
            csv.write("%.1f,%.1f,%.1f,%d,%d,%d,%s\n" % (s["t_s"], s["rss_mb"], s["cpu_percent"],
                      s["scans"], s["failed"], s["keyframes"], mode))
            csv.flush()
            if len(samples) % max(1, int(60 / args.sample_s)) == 0:
                print("[soak] %5.0f s  rss %.0f MB  cpu %.0f %%  scans %d  keyframes %d  overpass %s"
                      % (t, s["rss_mb"], s["cpu_percent"], s["scans"], s["keyframes"], mode),
                      flush=True)
        csv.close()
        procs.stop(play)
        set_fault(overpass + "/control", "normal")
        time.sleep(5.0)
        reply = subprocess.run(
            ["rosservice", "call", "/graph_backend/save_map",
             "{destination: '%s', resolution: 0.5}" % os.path.join(args.out, "map")],
            capture_output=True, text=True, env=env, timeout=300)
        saved = {"success": "success: True" in reply.stdout,
                 "message": (reply.stdout + reply.stderr).strip()[-500:]}
        saved["keyframes_made"] = c.keyframes_made  # by the scan matcher, every loop
        saved["keyframes_saved"] = 0
        missing = re.search(r"(\d+) keyframes missing", saved["message"])
        saved["keyframes_missing_reported"] = int(missing.group(1)) if missing else 0
        if saved["success"]:
            with open(os.path.join(args.out, "map", "trajectory_tum.txt")) as f:
                saved["keyframes_saved"] = sum(1 for line in f if not line.startswith("#"))
        manager_alive = os.path.exists("/proc/%d" % manager)
    finally:
        procs.stop_all()

    v = verdict(samples, args)
    v["stopped_early"] = stop.is_set()
    v["checks"]["ran_to_the_end"] = not stop.is_set()
    v["manager_alive"] = manager_alive
    v["save_map"] = saved
    v["checks"]["manager_alive"] = manager_alive
    v["checks"]["save_map"] = saved["success"]
    # Every keyframe the scan matcher made is in the saved graph.
    v["checks"]["every_keyframe_saved"] = saved["keyframes_saved"] >= saved["keyframes_made"] > 0
    # A keyframe lost anyway is never silent: save_map counts it.
    v["checks"]["every_loss_reported"] = (saved["keyframes_made"] - saved["keyframes_saved"]
                                          <= saved["keyframes_missing_reported"])
    if samples:
        v["final"] = samples[-1]
        v["cpu_percent_mean"] = sum(s["cpu_percent"] for s in samples) / len(samples)
    v["passed"] = all(v["checks"].values())
    with open(os.path.join(args.out, "soak.json.tmp"), "w") as f:
        json.dump(v, f, indent=2)
    os.replace(os.path.join(args.out, "soak.json.tmp"), os.path.join(args.out, "soak.json"))
    print("[soak] %s" % json.dumps(v, indent=2), flush=True)
    return 0 if v["passed"] else 1


if __name__ == "__main__":
    sys.exit(main())

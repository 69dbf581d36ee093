#!/usr/bin/python3
"""ROS helpers of scripts/demo.sh (rospy/rosbag; run with the workspace's devel/setup.bash sourced).

  demo_ros.py ground-truth BAG OUT.tum
      The bag's ground_truth (nav_msgs/Odometry, base_link in the ENU frame of the first GPS fix,
      which is also the SLAM map frame) as a TUM trajectory: every scan, not only the keyframes.
  demo_ros.py monitor BAG --ready-file F --bag-done-file F --report F.json [--timeout S] [--settle S]
      A rospy node on the running master. Phase 1: waits until every nodelet of
      osm_graph_slam.launch is up (their topics and the save_map service are registered), then
      writes --ready-file. Phase 2: counts scan-matching statuses, keyframes, segments, loop
      closures and back-end paths until, after --bag-done-file appeared, the back-end has the last
      keyframe in its optimised path, line_extraction has sent that keyframe's segments and no
      front-end input arrived for --settle seconds. Writes --report (JSON) and exits 0; exits 1
      (saying what is missing) after --timeout seconds without that.
"""
import argparse
import json
import os
import sys
import threading
import time


def bag_scans(bag_path, topic="velodyne_points"):
    """(number of scans, header stamp of the last scan) of the bag."""
    import rosbag
    import rospy

    with rosbag.Bag(bag_path) as bag:
        info = bag.get_type_and_topic_info().topics
        name = topic if topic in info else "/" + topic
        if name not in info:
            raise RuntimeError("%s has no %s topic" % (bag_path, topic))
        count = info[name].message_count
        last = None
        start = rospy.Time.from_sec(max(bag.get_end_time() - 1.0, bag.get_start_time()))
        for _, msg, _ in bag.read_messages(topics=[name], start_time=start):
            last = msg.header.stamp.to_sec()
    return count, last


def ground_truth(bag_path, out_path):
    import rosbag

    rows = []
    with rosbag.Bag(bag_path) as bag:
        for _, msg, _ in bag.read_messages(topics=["ground_truth", "/ground_truth"]):
            p, q = msg.pose.pose.position, msg.pose.pose.orientation
            rows.append("%.9f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n" % (
                msg.header.stamp.to_sec(), p.x, p.y, p.z, q.x, q.y, q.z, q.w))
    if not rows:
        sys.exit("demo_ros: %s has no ground_truth messages" % bag_path)
    tmp = out_path + ".tmp"
    with open(tmp, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw (ground_truth of %s)\n" % os.path.basename(bag_path))
        f.writelines(rows)
    os.replace(tmp, out_path)
    print("demo_ros: %d ground-truth poses -> %s" % (len(rows), out_path))


# Topics and services whose registration shows that each nodelet of osm_graph_slam.launch is loaded.
REQUIRED_SUBSCRIBED = {
    "/velodyne_points": "prefiltering",
    "/filtered_points": "scan_matching",
    "/keyframe": "line_extraction, loop_detection, graph_backend",
    "/gps/fix": "osm_buffer",
    "/line_segments": "graph_backend",
}
REQUIRED_PUBLISHED = {
    "/scan_matching_status": "scan_matching",
    "/line_segments": "line_extraction",
    "/loop_closures": "loop_detection",
    "/osm/origin": "osm_buffer",
    "/slam/path": "graph_backend",
}
SAVE_MAP = "/graph_backend/save_map"


def missing_nodelets(master):
    pubs, subs, services = master.getSystemState()
    subs = {t for t, nodes in subs if nodes}
    pubs = {t for t, nodes in pubs if nodes}
    services = {s for s, _ in services}
    missing = ["%s (subscriber of %s)" % (who, t) for t, who in REQUIRED_SUBSCRIBED.items()
               if t not in subs]
    missing += ["%s (publisher of %s)" % (who, t) for t, who in REQUIRED_PUBLISHED.items()
                if t not in pubs]
    if SAVE_MAP not in services:
        missing.append("graph_backend (service %s)" % SAVE_MAP)
    return missing


def write_atomically(path, text):
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


class Decoder:
    """Deserialises rospy.AnyMsg with a class generated from the publisher's message definition
    (as rosbag does): no generated Python message modules needed (Debian ships only C++ ones for
    nav_msgs and geometry_msgs)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.cls = None

    def __call__(self, raw):
        import genpy.dynamic

        with self.lock:
            if self.cls is None:
                header = raw._connection_header
                kind = header["type"]
                self.cls = genpy.dynamic.generate_dynamic(kind, header["message_definition"])[kind]
        return self.cls().deserialize(raw._buff)


def decoded(callback):
    decoder = Decoder()
    return lambda raw: callback(decoder(raw))


class Counters:
    """What the pipeline published, updated from the rospy callback threads."""

    def __init__(self):
        self.lock = threading.Lock()
        self.statuses = self.failed = self.keyframes = self.segments = self.loops = 0
        self.paths = 0
        self.last_status_stamp = None
        self.last_keyframe_stamp = None
        self.segment_stamps = set()
        self.path_last_stamp = None
        self.path_length = 0
        self.last_input_wall = time.monotonic()

    def on_status(self, msg):
        with self.lock:
            self.statuses += 1
            self.failed += int(msg.failed)
            self.last_status_stamp = msg.header.stamp.to_sec()
            if msg.new_keyframe:
                self.keyframes += 1
                self.last_keyframe_stamp = msg.header.stamp.to_sec()
            self.last_input_wall = time.monotonic()

    def on_segments(self, msg):
        with self.lock:
            self.segments += 1
            self.segment_stamps.add(round(msg.header.stamp.to_sec(), 6))
            self.last_input_wall = time.monotonic()

    def on_loop(self, _msg):
        with self.lock:
            self.loops += 1
            self.last_input_wall = time.monotonic()

    def on_path(self, msg):
        with self.lock:
            self.paths += 1
            self.path_length = len(msg.poses)
            if msg.poses:
                self.path_last_stamp = msg.poses[-1].header.stamp.to_sec()


def monitor(args):
    import rosgraph
    import rospy

    scans, last_scan_stamp = bag_scans(args.bag)
    master = rosgraph.Master("/demo_monitor")
    deadline = time.monotonic() + args.ready_timeout
    while True:
        try:
            missing = missing_nodelets(master)
        except Exception as e:  # master not reachable yet
            missing = ["the ROS master (%s)" % e]
        if not missing:
            break
        if time.monotonic() > deadline:
            sys.exit("demo_ros: after %.0f s still missing: %s" % (args.ready_timeout,
                                                                  "; ".join(missing)))
        time.sleep(0.5)

    rospy.init_node("demo_monitor", anonymous=True, disable_signals=True)
    c = Counters()
    subs = [
        rospy.Subscriber("/scan_matching_status", rospy.AnyMsg, decoded(c.on_status),
                         queue_size=1000),
        rospy.Subscriber("/line_segments", rospy.AnyMsg, decoded(c.on_segments), queue_size=100),
        rospy.Subscriber("/loop_closures", rospy.AnyMsg, c.on_loop, queue_size=100),
        rospy.Subscriber("/slam/path", rospy.AnyMsg, decoded(c.on_path), queue_size=2),
    ]
    deadline = time.monotonic() + 30.0
    while any(s.get_num_connections() == 0 for s in subs[:2]) and time.monotonic() < deadline:
        time.sleep(0.1)
    write_atomically(args.ready_file, "ready\n")

    started = time.monotonic()
    bag_done_at = None
    next_print = started + args.print_period
    while True:
        time.sleep(0.5)
        now = time.monotonic()
        if bag_done_at is None and os.path.exists(args.bag_done_file):
            bag_done_at = now
        with c.lock:
            front_end_caught_up = (c.last_status_stamp is not None and
                                   c.last_status_stamp >= last_scan_stamp - 1e-6)
            idle = now - c.last_input_wall >= args.settle
            kf = c.last_keyframe_stamp
            segments_done = kf is not None and round(kf, 6) in c.segment_stamps
            backend_done = (kf is not None and c.path_last_stamp is not None and
                            c.path_last_stamp >= kf - 1e-6)
            snapshot = dict(scans_in_bag=scans, scans_processed=c.statuses,
                            scans_dropped=scans - c.statuses, failed_matches=c.failed,
                            keyframes=c.keyframes, segment_messages=c.segments,
                            loop_closures=c.loops, backend_path_updates=c.paths,
                            backend_path_keyframes=c.path_length)
        if now >= next_print:
            next_print = now + args.print_period
            print("[demo]   front-end %d/%d scans, %d keyframes, %d loop closures, back-end path %d "
                  "keyframes" % (snapshot["scans_processed"], scans, snapshot["keyframes"],
                                 snapshot["loop_closures"], snapshot["backend_path_keyframes"]),
                  flush=True)
        if bag_done_at is None:
            continue
        # idle: no status/segments/loop for --settle s (a scan takes well under a second).
        if idle and segments_done and backend_done:
            snapshot["front_end_reached_last_scan"] = front_end_caught_up
            snapshot["wait_after_bag_s"] = round(now - bag_done_at, 1)
            write_atomically(args.report, json.dumps(snapshot, indent=1) + "\n")
            return 0
        if now - bag_done_at > args.timeout:
            why = []
            if kf is None:
                why.append("scan matching made no keyframe")
            else:
                if not segments_done:
                    why.append("no line_segments for the last keyframe (stamp %.3f)" % kf)
                if not backend_done:
                    why.append("the back-end's path ends at %s, not at the last keyframe %.3f" %
                               (c.path_last_stamp, kf))
            if not idle:
                why.append("the pipeline is still busy (front-end at %d of %d scans)" %
                           (c.statuses, scans))
            snapshot["error"] = "; ".join(why)
            write_atomically(args.report, json.dumps(snapshot, indent=1) + "\n")
            print("demo_ros: %.0f s after the bag ended: %s" % (args.timeout, snapshot["error"]),
                  file=sys.stderr)
            return 1


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    gt = sub.add_parser("ground-truth")
    gt.add_argument("bag")
    gt.add_argument("out")
    mon = sub.add_parser("monitor")
    mon.add_argument("bag")
    mon.add_argument("--ready-file", required=True)
    mon.add_argument("--bag-done-file", required=True)
    mon.add_argument("--report", required=True)
    mon.add_argument("--ready-timeout", type=float, default=90.0,
                     help="[s] for the nodelets to come up")
    mon.add_argument("--timeout", type=float, default=600.0,
                     help="[s] after the bag ended for the pipeline to finish")
    mon.add_argument("--settle", type=float, default=5.0,
                     help="[s] without new statuses, segments or loops = idle")
    mon.add_argument("--print-period", type=float, default=30.0)
    args = parser.parse_args()
    if args.cmd == "ground-truth":
        ground_truth(args.bag, args.out)
        return 0
    return monitor(args)


if __name__ == "__main__":
    sys.exit(main())

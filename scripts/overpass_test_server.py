#!/usr/bin/python3
"""A local stand-in for the Overpass API, for tests (loopback only, Python stdlib only).

Answers Overpass QL `around:R,lat,lon` building queries from a local .osm file with the same
geometry the real server uses: a building way (or multipolygon relation) is returned when any
segment of its outline lies within R metres of the point, or the point lies inside it; its nodes
(and a relation's member ways and their nodes) follow, as `out body; >; out skel qt;` does.

Faults for the client/buffer tests, chosen with --mode or at run time with
GET /control?mode=<mode>[&latency_ms=N]:
  normal      correct answer
  http429     HTTP 429 Too Many Requests          http504   HTTP 504 Gateway Timeout
  drop        connection closed without an answer
  short_read  Content-Length of the full answer, half of it sent, connection closed
  truncate    HTTP 200 with only the first half of the XML (consistent Content-Length)
  malformed   HTTP 200 with a broken XML document
  oversize    HTTP 200 streaming --oversize-bytes of XML padding
  remark      HTTP 200 with an Overpass "runtime error" remark (server-side timeout)
GET /stats returns JSON counters (requests, last query, User-Agent, Accept-Encoding).

  overpass_test_server.py --osm map.osm [--port 0] [--port-file F] [--latency-ms N] [--mode M]
The chosen port is printed as "PORT <n>" on stdout and written to --port-file (atomically).
"""
import argparse
import gzip
import json
import math
import os
import re
import socket
import sys
import threading
import time
import urllib.parse
import xml.etree.ElementTree as ET
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from xml.sax.saxutils import quoteattr

MODES = ("normal", "http429", "http504", "drop", "short_read", "truncate", "malformed",
         "oversize", "remark")
AROUND = re.compile(r"around:\s*([-+0-9.eE]+)\s*,\s*([-+0-9.eE]+)\s*,\s*([-+0-9.eE]+)")

# WGS84
A = 6378137.0
F = 1.0 / 298.257223563
E2 = F * (2.0 - F)


class OsmStore:
    """Nodes, building ways and building multipolygon relations of one .osm file."""

    def __init__(self, path):
        root = ET.parse(path).getroot()
        self.nodes = {}
        for n in root.iter("node"):
            self.nodes[n.get("id")] = (float(n.get("lat")), float(n.get("lon")))
        self.ways = {}  # id -> (refs, tags)
        for w in root.iter("way"):
            refs = [nd.get("ref") for nd in w.findall("nd")]
            tags = [(t.get("k"), t.get("v")) for t in w.findall("tag")]
            self.ways[w.get("id")] = (refs, tags)
        self.relations = {}  # id -> (members, tags)
        for r in root.iter("relation"):
            tags = [(t.get("k"), t.get("v")) for t in r.findall("tag")]
            keys = dict(tags)
            if "building" in keys and keys.get("type") == "multipolygon":
                members = [(m.get("type"), m.get("ref"), m.get("role") or "")
                           for m in r.findall("member")]
                self.relations[r.get("id")] = (members, tags)

    def building_way_ids(self):
        return [wid for wid, (_, tags) in self.ways.items() if any(k == "building" for k, _ in tags)]


class LocalPlane:
    """Tangent-plane metres around (lat0, lon0) with the ellipsoid's radii of curvature."""

    def __init__(self, lat0, lon0):
        phi = math.radians(lat0)
        s = math.sin(phi)
        w = math.sqrt(1.0 - E2 * s * s)
        self.m = A * (1.0 - E2) / (w ** 3)  # meridian radius
        self.n = A / w  # prime vertical radius
        self.cos0 = math.cos(phi)
        self.lat0, self.lon0 = lat0, lon0

    def xy(self, lat, lon):
        return (math.radians(lon - self.lon0) * self.n * self.cos0,
                math.radians(lat - self.lat0) * self.m)


def segment_distance(a, b):
    """Distance from the origin to segment ab."""
    ax, ay = a
    bx, by = b
    dx, dy = bx - ax, by - ay
    l2 = dx * dx + dy * dy
    t = 0.0 if l2 == 0.0 else max(0.0, min(1.0, -(ax * dx + ay * dy) / l2))
    return math.hypot(ax + t * dx, ay + t * dy)


def contains_origin(ring):
    inside = False
    j = len(ring) - 1
    for i in range(len(ring)):
        (xi, yi), (xj, yj) = ring[i], ring[j]
        if (yi > 0.0) != (yj > 0.0) and 0.0 < (xj - xi) * (0.0 - yi) / (yj - yi) + xi:
            inside = not inside
        j = i
    return inside


def within(points, radius):
    if not points:
        return False
    if len(points) == 1:
        return math.hypot(*points[0]) <= radius
    if any(segment_distance(points[i], points[i + 1]) <= radius for i in range(len(points) - 1)):
        return True
    closed = len(points) >= 4 and points[0] == points[-1]
    return closed and contains_origin(points)


def answer_around(store, radius, lat, lon):
    plane = LocalPlane(lat, lon)

    def way_points(wid):
        refs, _ = store.ways[wid]
        return [plane.xy(*store.nodes[r]) for r in refs if r in store.nodes]

    ways = [wid for wid in store.building_way_ids() if within(way_points(wid), radius)]
    relations = []
    for rid, (members, _) in store.relations.items():
        member_ways = [ref for t, ref, _ in members if t == "way" and ref in store.ways]
        pts_ok = any(within(way_points(w), radius) for w in member_ways)
        if pts_ok:
            relations.append(rid)

    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           '<osm version="0.6" generator="overpass_test_server">',
           '<note>Test data derived from OpenStreetMap (ODbL).</note>']
    for wid in ways:
        refs, tags = store.ways[wid]
        out.append('  <way id="%s">' % wid)
        out.extend('    <nd ref="%s"/>' % r for r in refs)
        out.extend("    <tag k=%s v=%s/>" % (quoteattr(k), quoteattr(v)) for k, v in tags)
        out.append("  </way>")
    skel_ways = set()
    for rid in relations:
        members, tags = store.relations[rid]
        out.append('  <relation id="%s">' % rid)
        for t, ref, role in members:
            out.append('    <member type="%s" ref="%s" role=%s/>' % (t, ref, quoteattr(role)))
            if t == "way" and ref in store.ways and ref not in ways:
                skel_ways.add(ref)
        out.extend("    <tag k=%s v=%s/>" % (quoteattr(k), quoteattr(v)) for k, v in tags)
        out.append("  </relation>")
    node_ids = set()
    for wid in list(ways) + sorted(skel_ways):
        node_ids.update(r for r in store.ways[wid][0] if r in store.nodes)
    for nid in sorted(node_ids, key=int):
        la, lo = store.nodes[nid]
        out.append('  <node id="%s" lat="%.7f" lon="%.7f"/>' % (nid, la, lo))
    for wid in sorted(skel_ways, key=int):
        out.append('  <way id="%s">' % wid)
        out.extend('    <nd ref="%s"/>' % r for r in store.ways[wid][0])
        out.append("  </way>")
    out.append("</osm>")
    return ("\n".join(out) + "\n").encode("utf-8"), len(ways), len(relations)


class State:
    def __init__(self, args, store):
        self.lock = threading.Lock()
        self.mode = args.mode
        self.latency_ms = args.latency_ms
        self.oversize_bytes = args.oversize_bytes
        self.store = store
        self.stats = {"requests": 0, "answered": 0, "last_query": "", "user_agent": "",
                      "accept_encoding": "", "last_buildings": 0, "last_mode": ""}


def make_handler(state):
    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def log_message(self, fmt, *args):  # quiet: tests read /stats instead
            pass

        def send_body(self, status, body, content_type="application/osm3s+xml", extra=None):
            gz = "gzip" in (self.headers.get("Accept-Encoding") or "") and len(body) > 256
            if gz:
                body = gzip.compress(body)
            self.send_response(status)
            self.send_header("Content-Type", content_type)
            self.send_header("Content-Length", str(len(body)))
            if gz:
                self.send_header("Content-Encoding", "gzip")
            for k, v in (extra or {}).items():
                self.send_header(k, v)
            self.end_headers()
            self.wfile.write(body)

        def do_GET(self):
            url = urllib.parse.urlparse(self.path)
            params = urllib.parse.parse_qs(url.query)
            if url.path == "/control":
                with state.lock:
                    if "mode" in params:
                        mode = params["mode"][0]
                        if mode not in MODES:
                            return self.send_body(400, b"unknown mode\n", "text/plain")
                        state.mode = mode
                    if "latency_ms" in params:
                        state.latency_ms = int(params["latency_ms"][0])
                    reply = {"mode": state.mode, "latency_ms": state.latency_ms}
                return self.send_body(200, json.dumps(reply).encode(), "application/json")
            if url.path == "/stats":
                with state.lock:
                    reply = dict(state.stats, mode=state.mode, latency_ms=state.latency_ms)
                return self.send_body(200, json.dumps(reply).encode(), "application/json")
            if "data" in params:
                return self.interpreter(params["data"][0])
            return self.send_body(404, b"not found\n", "text/plain")

        def do_POST(self):
            length = int(self.headers.get("Content-Length") or 0)
            form = urllib.parse.parse_qs(self.rfile.read(length).decode("utf-8", "replace"))
            if "data" not in form:
                return self.send_body(400, b"Error: no query in form field data\n", "text/plain")
            return self.interpreter(form["data"][0])

        def interpreter(self, query):
            with state.lock:
                state.stats["requests"] += 1
                state.stats["last_query"] = query
                state.stats["user_agent"] = self.headers.get("User-Agent") or ""
                state.stats["accept_encoding"] = self.headers.get("Accept-Encoding") or ""
                mode, latency_ms = state.mode, state.latency_ms
                state.stats["last_mode"] = mode
            if latency_ms > 0:
                time.sleep(latency_ms / 1000.0)
            m = AROUND.search(query)
            if not m:
                return self.send_body(400, b"Error: query has no around:R,lat,lon filter\n",
                                      "text/plain")
            radius, lat, lon = (float(g) for g in m.groups())
            if mode == "http429":
                return self.send_body(429, b"Too Many Requests: rate limited\n", "text/plain")
            if mode == "http504":
                return self.send_body(504, b"<html><body>504 Gateway Timeout</body></html>\n",
                                      "text/html")
            if mode == "drop":
                self.close_connection = True
                self.connection.shutdown(socket.SHUT_RDWR)
                return None
            if mode == "remark":
                body = ('<?xml version="1.0" encoding="UTF-8"?>\n<osm version="0.6">\n<remark> '
                        'runtime error: Query timed out in "query" at line 3 after 25 seconds. '
                        "</remark>\n</osm>\n").encode()
                return self.send_body(200, body)
            if mode == "oversize":
                return self.stream_oversize()
            body, n_ways, n_rel = answer_around(state.store, radius, lat, lon)
            if mode == "truncate":
                body = body[: len(body) // 2]
            elif mode == "malformed":
                body = body[: len(body) // 3] + b"<way id=\"oops\"><nd ref=<</osm>\n"
            elif mode == "short_read":
                self.send_response(200)
                self.send_header("Content-Type", "application/osm3s+xml")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body[: len(body) // 2])
                self.wfile.flush()
                self.close_connection = True
                self.connection.shutdown(socket.SHUT_RDWR)
                return None
            with state.lock:
                state.stats["answered"] += 1
                state.stats["last_buildings"] = n_ways + n_rel
            return self.send_body(200, body)

        def stream_oversize(self):
            chunk = b"<!-- " + b"x" * 65000 + b" -->\n"
            total = state.oversize_bytes
            self.send_response(200)
            self.send_header("Content-Type", "application/osm3s+xml")
            self.send_header("Content-Length", str(total))
            self.end_headers()
            sent = 0
            try:
                while sent < total:
                    part = chunk[: min(len(chunk), total - sent)]
                    self.wfile.write(part)
                    sent += len(part)
            except (BrokenPipeError, ConnectionResetError):
                pass  # the client aborted, as it should
            self.close_connection = True

    return Handler


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--osm", required=True, help=".osm XML file to answer from")
    parser.add_argument("--port", type=int, default=0, help="0 = pick a free port")
    parser.add_argument("--port-file", help="write the chosen port here")
    parser.add_argument("--latency-ms", type=int, default=0)
    parser.add_argument("--mode", choices=MODES, default="normal")
    parser.add_argument("--oversize-bytes", type=int, default=8 << 20)
    args = parser.parse_args()

    store = OsmStore(args.osm)
    state = State(args, store)
    ThreadingHTTPServer.allow_reuse_address = True
    ThreadingHTTPServer.daemon_threads = True
    server = ThreadingHTTPServer(("127.0.0.1", args.port), make_handler(state))
    port = server.server_address[1]
    if args.port_file:
        tmp = args.port_file + ".tmp"
        with open(tmp, "w") as f:
            f.write("%d\n" % port)
        os.replace(tmp, args.port_file)
    print("PORT %d" % port, flush=True)
    print("serving %d building ways, %d building relations from %s on 127.0.0.1:%d" %
          (len(store.building_way_ids()), len(store.relations), args.osm, port),
          file=sys.stderr, flush=True)
    try:
        server.serve_forever(poll_interval=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()


if __name__ == "__main__":
    main()

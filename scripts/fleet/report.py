"""What fleet_map.py shows: a one-line progress while the drives run (done/total, failed,
elapsed) and the summary at the end (drives, the merge's numbers, time per stage), as text and
as OUT/fleet_summary.json."""
import sys
import time


def format_duration(seconds):
    seconds = int(round(seconds))
    if seconds < 60:
        return "%d s" % seconds
    if seconds < 3600:
        return "%dm%02ds" % divmod(seconds, 60)
    return "%dh%02dm" % (seconds // 3600, seconds % 3600 // 60)


class Progress:
    """The progress line. On a terminal it is rewritten in place (carriage return); into a file
    or pipe a line is written only when a count changes, so a log does not fill with clocks."""

    def __init__(self, total, stream=None, clock=time.monotonic):
        self.total = total
        self.done = 0
        self.failed = 0
        self.stream = stream or sys.stdout
        self.clock = clock
        self.start = clock()
        self._last_counts = None
        self._tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def text(self):
        return "[fleet] drives %d/%d done, %d failed, %s elapsed" % (
            self.done, self.total, self.failed, format_duration(self.clock() - self.start))

    def finished_one(self, ok):
        self.done += 1
        if not ok:
            self.failed += 1
        self.show()

    def show(self):
        counts = (self.done, self.failed)
        if self._tty:
            self.stream.write("\r" + self.text() + "\x1b[K")
        elif counts != self._last_counts:
            self.stream.write(self.text() + "\n")
        self._last_counts = counts
        self.stream.flush()

    def end(self):
        if self._tty:
            self.stream.write("\n")
            self.stream.flush()


def stage_seconds(drive_rows):
    """{step: {"sum": s, "max": s}} over the drives run or read back (simulate, offline_slam)."""
    stages = {}
    for row in drive_rows:
        for step, secs in (row.get("step_seconds") or {}).items():
            s = stages.setdefault(step, {"sum": 0.0, "max": 0.0})
            s["sum"] = round(s["sum"] + secs, 1)
            s["max"] = max(s["max"], secs)
    return stages


def merge_section(merge):
    """The merge's part of the summary from tasks.run_merge's result (or {"error": ...})."""
    if "error" in merge:
        return {"made": False, "error": merge["error"]}
    summary = merge["summary"]
    keys = ("keyframes", "inter_session_loops", "buildings_by_drives", "merge_seconds")
    section = {"made": True, "complete": merge["exit"] == 0, "exit": merge["exit"],
               "task_seconds": merge["seconds"]}
    section.update({k: summary.get(k) for k in keys})
    return section


def mark_unreadable_sessions(sessions, merge):
    """Each session merge_sessions could not read gets in_map False and its error; the others
    in_map True (when a map was made)."""
    made = "error" not in merge
    by_dir = {}
    if made:
        for s in merge["summary"].get("sessions") or []:
            if isinstance(s, dict) and s.get("ok") is False:
                by_dir[s.get("dir")] = s.get("error") or "could not be read"
    for row in sessions:
        if row.get("dump") in by_dir:
            row["in_map"] = False
            row["error"] = "merge: %s" % by_dir[row["dump"]]
        else:
            row["in_map"] = made and row.get("dump") is not None


def fleet_document(sessions, merge, wall_seconds, out, command):
    drives = [r for r in sessions if r["status"] != "dump given"]
    failed = [r for r in drives if r["status"] == "failed"]
    return {
        "generated": time.strftime("%Y-%m-%d %H:%M:%S"),
        "command": command,
        "out": out,
        "map": merge_section(merge),
        "map_folder": None if "error" in merge else "%s/merged" % out,
        "counts": {"drives": len(drives), "ok": len(drives) - len(failed), "failed": len(failed),
                   "dumps_given": len(sessions) - len(drives),
                   "sessions_in_map": sum(1 for r in sessions if r.get("in_map"))},
        "sessions": sessions,
        "seconds": {"front_end": stage_seconds(drives), "merge": merge.get("seconds"),
                    "wall": round(wall_seconds, 1)},
    }


def summary_lines(doc):
    """The summary as text lines (printed at the end of fleet_map.py)."""
    c, m = doc["counts"], doc["map"]
    lines = ["[fleet] drives: %d ok, %d failed; %d dumps given" % (c["ok"], c["failed"], c["dumps_given"])]
    for r in doc["sessions"]:
        if r["status"] == "failed":
            lines.append("[fleet]   FAILED %s after %d tries: %s" % (r["name"], r.get("attempts", 0), r["error"]))
        elif r.get("in_map") is False and m["made"]:
            lines.append("[fleet]   NOT IN MAP %s (%s): %s" % (r["name"], r.get("dump"), r.get("error")))
    if not m["made"]:
        lines.append("[fleet] NO MAP: %s" % m["error"])
    else:
        lines.append("[fleet] map from %d of %d sessions%s: %s" % (
            c["sessions_in_map"], len(doc["sessions"]), "" if m["complete"] else " (partial)", doc["map_folder"]))
        lines.append("[fleet] keyframes %s, inter-session loops %s" % (m.get("keyframes"), m.get("inter_session_loops")))
        lines.append("[fleet] buildings by the number of drives that saw them: %s" % buildings_text(m.get("buildings_by_drives")))
    lines.append("[fleet] time: %s" % time_text(doc["seconds"], m))
    return lines


def buildings_text(by_drives):
    if not isinstance(by_drives, dict) or not by_drives:
        return "(none reported)"
    def as_number(k):
        try:
            return int(k)
        except (TypeError, ValueError):
            return float("inf")
    return ", ".join("%s drive%s: %s" % (k, "" if str(k) == "1" else "s", by_drives[k])
                     for k in sorted(by_drives, key=as_number))


def time_text(seconds, merge):
    in_pipeline_order = sorted(seconds["front_end"].items(), key=lambda kv: (kv[0] != "simulate", kv[0]))
    parts = ["%s per drive sum %s, max %s" % (step, format_duration(s["sum"]), format_duration(s["max"]))
             for step, s in in_pipeline_order]
    if seconds.get("merge") is not None:
        inner = merge.get("merge_seconds")
        parts.append("merge %s%s" % (format_duration(seconds["merge"]),
                                     " (merge_sessions reports %s)" % format_duration(inner)
                                     if isinstance(inner, (int, float)) else ""))
    parts.append("wall %s" % format_duration(seconds["wall"]))
    return "; ".join(parts)

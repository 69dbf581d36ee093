"""Reading and writing the matrix's files: atomic writes (a drive killed half-way leaves no
half-written result.json), JSON that may be missing, folder listings, and a tool log's last line
(the reason printed in the table's status column)."""
import json
import os
import re
import threading


def write_atomically(path, text):
    """Writes through a temporary file, so that a reader never sees half a file."""
    tmp = "%s.tmp.%d.%d" % (path, os.getpid(), threading.get_ident())
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def read_json(path):
    """The document, or None when the file is missing or unreadable."""
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def sorted_listdir(path):
    """The folder's entries, sorted; [] when it cannot be read (a step may not have made it)."""
    try:
        return sorted(os.listdir(path))
    except OSError:
        return []


def unwritable(folder):
    """None when `folder` exists (made if needed) and takes a file; else the reason."""
    try:
        os.makedirs(folder, exist_ok=True)
        probe = os.path.join(folder, ".slam_matrix_write_test")
        with open(probe, "w"):
            pass
        os.remove(probe)
    except OSError as e:
        return str(e.strerror or e)
    return None


ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


def last_log_line(path):
    """The log's last meaningful line (no colour codes, no progress bar), at most 300 characters."""
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            f.seek(max(0, size - 16384))
            text = f.read().decode("utf-8", "replace")
    except OSError:
        return ""
    for line in reversed(re.split(r"[\r\n]+", ANSI.sub("", text))):
        line = line.strip()
        if line and not re.fullmatch(r"\[[# ]*\]\s*\d+/\d+", line):  # skip progress bars
            return line[:300]
    return ""

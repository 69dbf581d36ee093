"""Puts scripts/ on a Dask worker's module path, so that the tasks' functions (fleet.tasks,
drive_matrix.one_drive), which Dask sends by name, import there.

Two ways in, for two kinds of workers:
- a worker started by hand: `dask-worker ADDRESS --preload /REPO/scripts/fleet/worker_path.py`
  runs this file when the worker starts (the module-level call below);
- a worker of a running cluster, or one that joins or is restarted later: cluster.py registers
  ScriptsOnPath as a worker plugin. Dask pickles the plugin; this module is pickled by value
  (cloudpickle.register_pickle_by_value), since a worker cannot import it before the path is set.
"""
import os
import sys

from distributed.diagnostics.plugin import WorkerPlugin

SCRIPTS = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def put_on_path(folder):
    if folder not in sys.path:
        sys.path.insert(0, folder)


class ScriptsOnPath(WorkerPlugin):
    """A worker plugin (Dask calls setup(worker) on every worker, now and when one joins)."""

    name = "osm_graph_slam_scripts_on_path"  # one registration per cluster, replaced if made again

    def __init__(self, folder=SCRIPTS):
        self.folder = folder

    def setup(self, worker=None):
        put_on_path(self.folder)


put_on_path(SCRIPTS)  # as a --preload file

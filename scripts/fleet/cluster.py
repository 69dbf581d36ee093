"""The Dask client both fleet_map.py and the drive matrix (--executor dask) run on: a
LocalCluster sized to this machine, or an existing cluster given by its scheduler's address,
used as it is. Either way scripts/ is put on every worker's module path (worker_path.py).

A LocalCluster has one thread per worker process: each task runs a C++ tool that uses the
cores itself, and a worker killed while it runs a drive is then a real fault (its one drive is
rescheduled), as on a cluster of machines."""
import logging
import os

import cloudpickle
from distributed import Client, LocalCluster

from . import worker_path


def default_workers(cores=None):
    """Drives at a time on this machine: one per core. A drive's tools keep 0.76 cores busy on
    average (doc/matrix.md, "Time budget": their serial parts), so two drives on two cores
    overlap one's serial parts with the other's parallel ones, as the matrix's --jobs 2 does
    (doc/fleet.md, "Workers")."""
    return max(1, cores or os.cpu_count() or 1)


def local_cluster(workers):
    """A LocalCluster of `workers` processes, one thread each, no dashboard (no web port), the
    scheduler on a free local port. Its warnings (a task's error, a worker restarted) are not
    printed: the progress line and the summary report each drive's fate."""
    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                        dashboard_address=None, scheduler_port=0, host="127.0.0.1",
                        silence_logs=logging.ERROR)


def connect(scheduler=None, workers=None):
    """(client, cluster): a client of the cluster at `scheduler` (cluster None: it is not ours
    to close), else of a new LocalCluster of `workers` (default_workers() when None)."""
    if scheduler:
        client, cluster = Client(scheduler), None
    else:
        cluster = local_cluster(workers or default_workers())
        client = Client(cluster)
    put_scripts_on_workers(client)
    return client, cluster


def put_scripts_on_workers(client):
    """Registers worker_path.ScriptsOnPath on the cluster: every worker, also one that joins
    or is restarted later, can then import fleet and drive_matrix."""
    cloudpickle.register_pickle_by_value(worker_path)
    plugin = worker_path.ScriptsOnPath()
    if hasattr(client, "register_plugin"):  # distributed >= 2023.9
        client.register_plugin(plugin, name=plugin.name)
    else:
        client.register_worker_plugin(plugin, name=plugin.name)


def close(client, cluster):
    """Closes the client, and the cluster when it is ours (a LocalCluster)."""
    try:
        client.close()
    finally:
        if cluster is not None:
            cluster.close()

"""Many drives, one map (scripts/fleet_map.py, doc/fleet.md): every drive's front-end as a Dask
task, then merge_sessions over their dumps. One module per concern, each depending only on
those above it (and on drive_matrix's files, steps and tools):

    worker_path.py  scripts/ on a Dask worker's module path (worker plugin, --preload file)
    cluster.py      the Dask client: a LocalCluster sized to the machine or a running cluster
    plan.py         which sessions: simulated drives, KITTI raw folders, given dumps; resume
    tasks.py        on a worker: one drive (simulate_urban, offline_slam --dump), the merge
    report.py       the progress line and the summary (text and fleet_summary.json)
    run.py          drives as tasks with retries, progress, then the merge task
    consensus.py    fleet_consensus.py: the first N drives merged and scored against the truth
    cli.py          the options, main() and the exit status

The drive matrix's --executor dask uses cluster.py too. Needs python3-distributed (Debian).
"""

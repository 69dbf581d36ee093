"""The drive matrix behind scripts/slam_matrix.py (doc/matrix.md), one module per concern, each
depending only on those above it:

    files.py         atomic writes, JSON that may be missing, a tool log's last line
    drives.py        one drive: world, simulate_urban axes, folder name, flags, SLAM runs, time estimate
    grid.py          presets and the grid of drives from the axes
    evaluation.py    one row's numbers from evaluate_slam's / offline_slam's / the simulator's JSON
    ground_truth.py  the true pose of every scan in offline_slam's map frame
    own_metrics.py   coverage, heading, odometry tilt, absolute offset bound (the matrix's own)
    table.py         the table, median and worst rows, the worst drive, --check's limits
    mode_summary.py  median and worst drive per GNSS mode, against the mode's baseline
    tools.py         running a tool in its own process group; evaluate_slam's known options
    steps.py         simulate_urban and the SLAM runs (or their --replay); flags a tool lacks
    one_drive.py     one drive: its steps, evaluate, result.json
    scheduler.py     which drives run, --jobs at a time (threads, or Dask tasks); the time estimate
    cli.py           the options, main() and the exit status

Python 3 standard library only; the Dask executor (--executor dask, --scheduler) also needs
python3-distributed and uses ../fleet/cluster.py.
"""

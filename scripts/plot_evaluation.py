#!/usr/bin/env python3
"""PNG plots of a SLAM evaluation from the plot_data.json written by evaluate_slam.

  plot_evaluation.py DIR   ->  DIR/trajectory.png, DIR/error_along_path.png, DIR/buildings.png
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")  # headless
import matplotlib.pyplot as plt  # noqa: E402


def plot_outlines(ax, buildings, **style):
    first = True
    for b in buildings:
        ring = b["outline"]
        if len(ring) < 3:
            continue
        xs = [p[0] for p in ring] + [ring[0][0]]
        ys = [p[1] for p in ring] + [ring[0][1]]
        ax.plot(xs, ys, label=style.pop("label", None) if first else None, **style)
        first = False


def main(folder):
    with open(os.path.join(folder, "plot_data.json")) as f:
        data = json.load(f)
    slam = data["slam"]
    base = data.get("baseline")
    label = data.get("baseline_label", "baseline")
    written = []

    fig, ax = plt.subplots(figsize=(8, 8))
    gt = slam["ground_truth_xy"]
    ax.plot([p[0] for p in gt], [p[1] for p in gt], "k-", lw=2, label="ground truth")
    if base:
        ax.plot([p[0] for p in base["estimate_xy"]], [p[1] for p in base["estimate_xy"]],
                "-", color="tab:orange", lw=1, label=label)
    ax.plot([p[0] for p in slam["estimate_xy"]], [p[1] for p in slam["estimate_xy"]],
            "-", color="tab:blue", lw=1, label="slam (OSM priors)")
    ax.set_aspect("equal")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.legend()
    ax.set_title("Trajectory")
    path = os.path.join(folder, "trajectory.png")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    written.append(path)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(slam["distance"], slam["ate"], color="tab:blue", label="slam (OSM priors)")
    if base:
        ax.plot(base["distance"], base["ate"], color="tab:orange", label=label)
    ax.set_xlabel("distance along path [m]")
    ax.set_ylabel("position error [m]")
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title("Absolute trajectory error along the path")
    path = os.path.join(folder, "error_along_path.png")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    written.append(path)
    plt.close(fig)

    if data.get("buildings_true"):
        fig, ax = plt.subplots(figsize=(9, 9))
        plot_outlines(ax, data["buildings_true"], color="k", lw=2, label="true")
        plot_outlines(ax, data.get("buildings_prior", []), color="tab:red", lw=1, ls="--",
                      label="OSM prior")
        plot_outlines(ax, data.get("buildings_corrected", []), color="tab:green", lw=1,
                      label="corrected")
        ax.plot([p[0] for p in slam["estimate_xy"]], [p[1] for p in slam["estimate_xy"]],
                "-", color="tab:blue", lw=0.8, label="slam trajectory")
        ax.set_aspect("equal")
        ax.legend()
        ax.set_title("Buildings before / after correction")
        path = os.path.join(folder, "buildings.png")
        fig.savefig(path, dpi=120, bbox_inches="tight")
        written.append(path)
        plt.close(fig)

    for p in written:
        print(p)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])

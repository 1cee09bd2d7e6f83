#!/usr/bin/env python3
"""Log-log plot of RMSE against render time from `kdtrace bench converge` CSV output.

Usage: plot_converge.py converge.csv converge.png
Draws one line per configuration and a t^(-1/2) guide through the first configuration.
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    curves = {}
    with open(sys.argv[1], newline="") as f:
        for row in csv.DictReader(f):
            t, e = float(row["seconds"]), float(row["rmse"])
            if t > 0 and e > 0:
                curves.setdefault(row["config"], []).append((t, e))
    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=100)
    for name, pts in curves.items():
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], marker="o", label=name)
    if curves:
        t0, e0 = next(iter(curves.values()))[0]
        ts = [p[0] for pts in curves.values() for p in pts]
        t1 = max(ts)
        ax.loglog([t0, t1], [e0, e0 * (t1 / t0) ** -0.5], "k--", lw=0.8, label="slope -1/2")
    ax.set_xlabel("render time [s]")
    ax.set_ylabel("RMSE against reference")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(sys.argv[2])


if __name__ == "__main__":
    main()

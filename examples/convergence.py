#!/usr/bin/env python3
"""Convergence of MC, QMC and BMC irradiance on the bundled Cornell box,
measured through a running service: relative RMS error against the number of
hemisphere samples N (log-log), and how often each estimator's error bar
(±2σ) covers the error.

    cargo run --release -- serve &
    pip install './python[plot]'
    python3 examples/convergence.py --url http://127.0.0.1:8080 --out docs/python-convergence.png

The reference at each point is plain Monte Carlo with 4096 samples and
independent seeds averaged (``--reference-seeds``); its own standard error
enters every coverage test (|error| ≤ 2·sqrt(σ² + σ_ref²)) and is drawn as
the floor below which errors cannot be resolved. Errors pool points, seeds
and RGB channels: relative RMSE = sqrt(mean(error²)) / mean(reference).
Irradiance is in W/m².
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from bmc_irradiance import Client
from cornell_points import cornell_points

METHODS = {"mc": "MC", "qmc": "QMC (Fibonacci)", "bmc": "BMC"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", default="http://127.0.0.1:8080")
    parser.add_argument("--scene", default="cornell-box", help="a Cornell-box scene id")
    parser.add_argument("--points", type=int, default=60)
    parser.add_argument("--seeds", type=int, default=6, help="request seeds per method and N")
    parser.add_argument("--samples", default="16,32,64,128,256,512", help="values of N")
    parser.add_argument("--reference-seeds", type=int, default=16)
    parser.add_argument("--max-depth", type=int, default=16)
    parser.add_argument("--out", default="convergence.png")
    args = parser.parse_args()
    counts = [int(n) for n in args.samples.split(",")]

    client = Client(args.url, timeout=600)
    positions, normals = cornell_points(args.points)
    started = time.monotonic()
    runs = [
        client.irradiance(
            args.scene, positions, normals, method="mc", samples=4096,
            max_depth=args.max_depth, seed=10_000 + k,
        )
        for k in range(args.reference_seeds)
    ]
    reference = np.mean([r.value for r in runs], axis=0)
    reference_sd = np.sqrt(np.sum([r.std_dev**2 for r in runs], axis=0)) / len(runs)
    mean_reference = reference.mean()
    floor = np.sqrt(np.mean(reference_sd**2)) / mean_reference
    print(
        f"reference: {args.points} points, {4096 * len(runs)} MC samples each, "
        f"relative standard error {floor:.4f} ({time.monotonic() - started:.0f} s)",
        file=sys.stderr,
    )

    table = {m: {"nrmse": [], "coverage": []} for m in METHODS}
    for n in counts:
        for method in METHODS:
            squared, covered, total = 0.0, 0, 0
            for seed in range(1, args.seeds + 1):
                r = client.irradiance(
                    args.scene, positions, normals, method=method, samples=n,
                    max_depth=args.max_depth, seed=seed,
                )
                error = r.value - reference
                squared += float(np.sum(error**2))
                covered += int(np.sum(np.abs(error) <= 2 * np.sqrt(r.std_dev**2 + reference_sd**2)))
                total += error.size
            nrmse = np.sqrt(squared / total) / mean_reference
            table[method]["nrmse"].append(nrmse)
            table[method]["coverage"].append(covered / total)
            print(f"N={n:4d} {method:3s}  relative RMSE {nrmse:.4f}  ±2σ coverage {covered / total:6.1%}",
                  file=sys.stderr)

    print("| N | " + " | ".join(f"{label} rel. RMSE" for label in METHODS.values())
          + " | " + " | ".join(f"{label} ±2σ cov." for label in METHODS.values()) + " |")
    print("|---" * (1 + 2 * len(METHODS)) + "|")
    for i, n in enumerate(counts):
        cells = [f"{table[m]['nrmse'][i]:.4f}" for m in METHODS]
        cells += [f"{table[m]['coverage'][i]:.0%}" for m in METHODS]
        print(f"| {n} | " + " | ".join(cells) + " |")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, cov) = plt.subplots(1, 2, figsize=(10, 4), gridspec_kw={"width_ratios": [3, 2]})
    for method, label in METHODS.items():
        ax.loglog(counts, table[method]["nrmse"], "o-", label=label)
        cov.semilogx(counts, 100 * np.array(table[method]["coverage"]), "o-", label=label)
    mc0 = table["mc"]["nrmse"][0]
    ax.loglog(counts, [mc0 * (counts[0] / n) ** 0.5 for n in counts], "k:", lw=1, label=r"$\propto N^{-1/2}$")
    ax.axhline(floor, color="grey", lw=1, ls="--", label="reference's own error")
    ax.set_xlabel("hemisphere samples per point N")
    ax.set_ylabel("relative RMS error of irradiance")
    ax.set_title(f"{args.scene}: {args.points} points × {args.seeds} seeds, max depth {args.max_depth}")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    cov.axhline(95.4, color="k", lw=1, ls=":", label="ideal 95.4 %")
    lowest = min(min(table[m]["coverage"]) for m in METHODS)
    cov.set_ylim(min(80.0, 100 * lowest - 5), 101)
    cov.set_xlabel("N")
    cov.set_ylabel("errors within ±2σ (%)")
    cov.set_title("error bar coverage")
    cov.legend(fontsize=8, loc="lower right")
    cov.grid(True, which="both", alpha=0.3)
    for axes in (ax, cov):
        axes.set_xticks(counts, [str(n) for n in counts])
        axes.minorticks_off()
    fig.tight_layout()
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Compare `bmc-irradiance irradiance --std-error` output with a reference CSV.

Usage: compare_irradiance.py OURS.csv REFERENCE.csv

OURS has columns x,y,z,r,g,b,se_r,se_g,se_b (the CLI's output with
--std-error); REFERENCE has x,y,z,nx,ny,nz,r,g,b,se_r,se_g,se_b (the Mitsuba
scripts' output). Rows are matched by order. Prints a Markdown table with, per
channel, the relative difference and z = (ours - ref) / sqrt(se_ours² + se_ref²),
then a summary over all channels where either value is non-zero.
"""
import csv
import math
import sys


def rows(path, first_value):
    with open(path, newline="") as f:
        data = list(csv.reader(f))[1:]
    return [(r[:first_value], [float(v) for v in r[first_value:first_value + 6]]) for r in data]


def main():
    ours = rows(sys.argv[1], 3)
    ref = rows(sys.argv[2], 6)
    if len(ours) != len(ref):
        sys.exit(f"row counts differ: {len(ours)} vs {len(ref)}")
    print("| # | point, normal | ours (r, g, b) | reference (r, g, b) | rel. diff (r, g, b) | z (r, g, b) |")
    print("|---|---|---|---|---|---|")
    zs, rels = [], []
    for i, ((_, a), (key, b)) in enumerate(zip(ours, ref)):
        rel_cells, z_cells = [], []
        for c in range(3):
            e, m = a[c], b[c]
            se = math.hypot(a[c + 3], b[c + 3])
            if e == 0 and m == 0:
                rel_cells.append("0 = 0")
                z_cells.append("-")
                continue
            z = (e - m) / se if se > 0 else math.inf
            rel = (e - m) / m if m else math.inf
            zs.append(z)
            rels.append(rel)
            rel_cells.append(f"{100 * rel:+.2f}%")
            z_cells.append(f"{z:+.2f}")
        fmt = lambda v: ", ".join(f"{x:.5f}" for x in v[:3])
        print(f"| {i} | ({', '.join(key[:3])}), ({', '.join(key[3:6])}) | {fmt(a)} | {fmt(b)} "
              f"| {', '.join(rel_cells)} | {', '.join(z_cells)} |")
    rms = math.sqrt(sum(z * z for z in zs) / len(zs))
    print()
    print(f"{len(zs)} channels: rms z = {rms:.2f}, max |z| = {max(map(abs, zs)):.2f}, "
          f"max |rel. diff| = {100 * max(map(abs, rels)):.2f}%, mean rel. diff = {100 * sum(rels) / len(rels):+.3f}%")


if __name__ == "__main__":
    main()

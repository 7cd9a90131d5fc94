#!/usr/bin/env python3
"""Format an irradiance CSV (x,y,z,nx,ny,nz,r,g,b,se_r,se_g,se_b) as a Markdown table.

Example:
    python results_tables.py data/mitsuba_irradiance_gi.csv
"""
import argparse
import csv


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv")
    ap.add_argument("--digits", type=int, default=5)
    args = ap.parse_args(argv)
    rows = list(csv.DictReader(open(args.csv)))
    print("| # | point (x,y,z) | normal | E_r | E_g | E_b | rel. SE (r,g,b) |")
    print("|---|---|---|---|---|---|---|")
    for i, r in enumerate(rows):
        p = ", ".join(f"{float(r[k]):g}" for k in "xyz")
        n = ", ".join(f"{float(r[k]):g}" for k in ("nx", "ny", "nz"))
        e = [float(r[c]) for c in "rgb"]
        se = [float(r["se_" + c]) for c in "rgb"]
        rse = ", ".join(f"{s / v * 100:.2f}%" if v > 0 else "-" for v, s in zip(e, se))
        print(f"| {i} | ({p}) | ({n}) | " + " | ".join(f"{v:.{args.digits}f}" for v in e) + f" | {rse} |")


if __name__ == "__main__":
    main()

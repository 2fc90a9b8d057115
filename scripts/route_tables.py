#!/usr/bin/env python3
"""The tables of docs/results.md's whole-line section, from two `tiltsim route` directories.

Usage: route_tables.py ROUTE_DIR RHO_DIR
Writes ROUTE_DIR/line.md (journey times, each vehicle's summary, the EN 12299 reading
sensitivity), ROUTE_DIR/transitions.md (every transition: chainage, radius, speed and P_CT per
vehicle, the limits that bind on the MPC-KF) and RHO_DIR/trade-off.md (each controller over ρ:
P_CT, N_MV, the doses, journey time), each from route.md and the CSV files.
"""

from __future__ import annotations

import csv
import os
import sys


def section(md: str, start: str) -> str:
    """The text of `md` from the line starting `start` to the next blank line after a table."""
    lines = md.splitlines()
    i = next(k for k, l in enumerate(lines) if l.startswith(start))
    out = []
    for l in lines[i:]:
        if out and not l.strip() and out[-1].startswith("|"):
            break
        out.append(l)
    return "\n".join(out)


def main(route: str, rho: str) -> None:
    md = open(os.path.join(route, "route.md")).read()
    with open(os.path.join(route, "line.md"), "w") as f:
        f.write(section(md, "Speed profiles:") + "\n\n")
        f.write(section(md, "| variant | controller |") + "\n\n")
        f.write(section(md, "P_CT standing over the route") + "\n")
    rows = list(csv.DictReader(open(os.path.join(route, "transitions.csv"))))
    variants = list(dict.fromkeys(r["variant"] for r in rows))
    by = {(r["variant"], r["curve"], r["transition"]): r for r in rows}
    keys = list(dict.fromkeys((r["curve"], r["transition"]) for r in rows))
    last = variants[-1]
    with open(os.path.join(route, "transitions.md"), "w") as f:
        f.write("| curve | transition | chainage (m) | R (m) | cant (mm) | shape | "
                + " | ".join(f"{v}: speed (km/h) / P_CT standing (%)" for v in variants)
                + f" | binding ({last}) |\n")
        f.write("|---" * (7 + len(variants)) + "|\n")
        for c, t in keys:
            first = by[(variants[0], c, t)]
            cells = [f"{float(by[(v, c, t)]['speed_kmh']):.1f} / {float(by[(v, c, t)]['p_ct_standing_pct']):.2f}"
                     for v in variants]
            f.write(f"| {c} | {t} | {float(first['chainage_m']):.0f} | {float(first['radius_m']):.0f} "
                    f"| {float(first['cant_mm']):.0f} | {first['shape']} | " + " | ".join(cells)
                    + f" | {by[(last, c, t)]['binding']} |\n")
    vr = list(csv.DictReader(open(os.path.join(rho, "variants.csv"))))
    with open(os.path.join(rho, "trade-off.md"), "w") as f:
        f.write("| controller | ρ | P_CT standing worst / mean (%) | N_MV straights median | "
                "window seat: lateral dose per hour (m/s^1.5) | roll-acceleration dose per hour (rad/s^1.5) "
                "| MSDV_z per hour (m/s^1.5) | journey time (s) |\n|---|---|---|---|---|---|---|---|\n")
        for r in vr:
            f.write(f"| {r['controller']} | {float(r['rho']):.2f} | {float(r['p_ct_worst_pct']):.2f} / "
                    f"{float(r['p_ct_mean_pct']):.2f} | {float(r['n_mv_median']):.3f} | "
                    f"{float(r['seat-window_msdv_y_per_hour']):.3f} | {float(r['seat-window_msdv_roll_per_hour']):.4f} | "
                    f"{float(r['seat-window_msdv_z_per_hour']):.4f} | {float(r['journey_time_s']):.0f} |\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])

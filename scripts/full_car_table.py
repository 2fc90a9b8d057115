#!/usr/bin/env python3
"""The headline controllers on the half vehicle and the whole car: a markdown table from the
runs scripts/results.sh makes in DIR/<scenario>-<model>/ (summary.json of each)."""
import json
import os
import sys

d = sys.argv[1]
runs = [
    ("deterministic", "passive", "paper-passive"),
    ("deterministic", "PI-drive", "pi-drive"),
    ("deterministic", "LQG", "paper-lqg"),
    ("deterministic", "MPC-KF", "paper-mpc"),
    ("irregular", "passive", "irregular-track"),
    ("irregular", "PI-drive", "pi-drive-irregular"),
    ("irregular", "LQG", "lqg-irregular"),
    ("irregular", "MPC-KF", "mpc-irregular"),
]


def load(scenario, model):
    return json.load(open(os.path.join(d, f"{scenario}-{model}", "summary.json")))


print("| track | controller | P_CT EN 12299 standing (%) half / full | P_CT paper's form (%) half / full "
      "| N_MV lateral half / full | deflection peak (mm) half / full "
      "| full: P_CT EN 12299 over leading bogie / centre / trailing bogie (%) "
      "| full: N_MV lateral there | full: binding safety limit (value / limit) | full: limit exceeded |")
print("|---|---|---|---|---|---|---|---|---|---|")
for track, name, sc in runs:
    h, f = load(sc, "half"), load(sc, "full")
    hc, fc = h["comfort"], f["comfort"]
    places = f["full_car"]["comfort_along_car"]
    flag = f["flags"]["running_safety"]
    bind = next(q for q in f["full_car"]["running_safety"] if q["quantity"] == flag["binding"])
    exceeded = ", ".join(
        f"{q['quantity']} {q['utilisation']:.2f} at wheelset {q['wheelset']}"
        for q in f["full_car"]["running_safety"] if q["exceeded"]) or "none"
    pct = " / ".join("%.2f" % p["p_ct_standing"] for p in places)
    nmv = " / ".join("%.2f" % p["n_mv_lateral"] for p in places)
    print(
        f"| {track} | {name} "
        f"| {hc['p_ct_en12299']['standing_pct']:.2f} / {fc['p_ct_en12299']['standing_pct']:.2f} "
        f"| {hc['p_ct_paper']['standing_pct']:.2f} / {fc['p_ct_paper']['standing_pct']:.2f} "
        f"| {hc['ride']['n_mv_lateral']:.2f} / {fc['ride']['n_mv_lateral']:.2f} "
        f"| {hc['deflection_peak_mm']:.1f} / {fc['deflection_peak_mm']:.1f} "
        f"| {pct} | {nmv} "
        f"| {bind['quantity']} at wheelset {bind['wheelset']}: {bind['utilisation']:.2f} "
        f"| {exceeded} |"
    )

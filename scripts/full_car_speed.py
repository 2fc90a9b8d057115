#!/usr/bin/env python3
"""Running safety of the whole car against speed on the curve: from runs that
scripts/results.sh makes in DIR/<vehicle>-<speed>/ (`tiltsim run scenarios/tilting-<vehicle>.toml
--set vehicle.model=full --set track.speed_kmh=<speed>`), for each vehicle the binding
running-safety quantity at every speed, and the first speed at which a limit is exceeded."""
import json
import os
import sys

d = sys.argv[1]
vehicles = sys.argv[2:]
runs = {}
for name in os.listdir(d):
    v, _, kmh = name.rpartition("-")
    if v in vehicles:
        runs.setdefault(v, []).append((float(kmh), json.load(open(os.path.join(d, name, "summary.json")))))
print("| vehicle | speed (km/h) | cant deficiency (mm) | binding quantity (wheelset): value / limit "
      "| (Y/Q)_2m | (SumY)_2m (kN) | dQ/Q0 | exceeded |")
print("|---|---|---|---|---|---|---|---|")
for v in vehicles:
    first = None
    for kmh, s in sorted(runs.get(v, []), key=lambda x: x[0]):
        # 1.5 m between rail centres; the paper's curve: R = 1000 m, 6 deg cant.
        cd = 1500.0 * ((kmh / 3.6) ** 2 / (9.81 * 1000.0) - 0.10510423526567646)
        q = {x["quantity"]: x for x in s["full_car"]["running_safety"]}
        flag = s["flags"]["running_safety"]
        b = q[flag["binding"]]
        exceeded = ", ".join(x["quantity"] for x in q.values() if x["exceeded"]) or "none"
        if flag["raised"] and first is None:
            first = kmh
        yq = q["(Y/Q)_2m"]["value"]
        print(f"| {v} | {kmh:.0f} | {cd:.0f} | {b['quantity']} ({b['wheelset']}): {b['utilisation']:.2f} "
              f"| {'lifted' if yq is None else f'{yq:.2f}'} | {q['(SumY)_2m']['value'] / 1000:.1f} "
              f"| {q['dQ/Q0']['value']:.2f} | {exceeded} |")
    print(f"| {v} | first limit exceeded at | {'none in the sweep' if first is None else f'{first:.0f} km/h'} | | | | | |")

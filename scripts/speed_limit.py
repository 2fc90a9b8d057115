#!/usr/bin/env python3
"""The highest speed on the curve at which each controller keeps the passengers' comfort
within the passive vehicle's at its design speed: from speed sweeps (`tiltsim sweep
SCENARIO --grid track.speed_kmh=...`), one per vehicle, and the passive run at the design
speed.

Usage: speed_limit.py OUT_DIR REFERENCE_SUMMARY PASSIVE_SWEEP SWEEP...
Writes OUT_DIR/speed-limit.md (the table) and OUT_DIR/speed-limit.svg (P_CT against speed).

The comfort is P_CT standing, EN 12299's evaluation. A sample counts only if it completed
and its comfort is valid (no oscillation, P_CT within the formula's 0-100 %); the limit is
where P_CT crosses the reference, linearly interpolated between the two grid speeds around
the crossing. Bump-stop contact is said, not excluded (the stops are a force of the model).
"""

from __future__ import annotations

import csv
import json
import os
import sys

KEY = "p_ct_en12299_standing_pct"
INVALID = ("oscillation", "P_CT > 100")


def samples(d: str) -> tuple[str, list[dict]]:
    rows = list(csv.DictReader(open(os.path.join(d, "samples.csv"))))
    rows.sort(key=lambda r: float(r["track.speed_kmh"]))
    name = os.path.basename(os.path.normpath(d))
    return name, rows


def valid(r: dict) -> bool:
    return r["status"] == "completed" and not any(f in r["validity_flags"] for f in INVALID)


def limit(rows: list[dict], ref: float) -> tuple[str, float | None]:
    """The crossing speed (km/h) and how it was found."""
    prev = None
    for r in rows:
        v, p = float(r["track.speed_kmh"]), float(r[KEY])
        if not valid(r):
            return ("comfort not valid from here", prev[0] if prev else None)
        if p > ref:
            if prev is None:
                return ("above the reference at the lowest speed", None)
            v0, p0 = prev
            return ("interpolated", v0 + (ref - p0) * (v - v0) / (p - p0))
        prev = (v, p)
    return ("below the reference at the highest speed", prev[0] if prev else None)


def main(out: str, reference: str, passive: str, sweeps: list[str]) -> None:
    s = json.load(open(reference))
    ref = s["comfort"]["p_ct_en12299"]["standing_pct"]
    design = s.get("scenario", "passive")
    series = []
    md = [f"Reference: {design} at its design speed, P_CT standing (EN 12299) {ref:.2f} %.", "",
          "| vehicle | highest speed within the reference (km/h) | how | cant deficiency there (mm) "
          "| bump-stop contact from (km/h) |",
          "|---|---|---|---|---|"]
    for d in [passive, *sweeps]:
        name, rows = samples(d)
        how, v = limit(rows, ref)
        # 1.5 m between rail centres; the paper's curve: R = 1000 m, 6 deg cant.
        deficiency = lambda kmh: 1500.0 * ((kmh / 3.6) ** 2 / (9.81 * 1000.0) - 0.10510423526567646)
        contact = next((float(r["track.speed_kmh"]) for r in rows
                        if float(r["deflection_peak_mm"]) >= 60.0), None)
        md.append(f"| {name} | {'—' if v is None else f'{v:.1f}'} | {how} "
                  f"| {'—' if v is None else f'{deficiency(v):.0f}'} "
                  f"| {'none' if contact is None else f'{contact:.0f}'} |")
        series.append((name, [(float(r["track.speed_kmh"]), float(r[KEY]), valid(r)) for r in rows]))
    open(os.path.join(out, "speed-limit.md"), "w").write("\n".join(md) + "\n")

    colours = ["#7f7f7f", "#1f77b4", "#2ca02c", "#d62728", "#9467bd"]
    W, H, L, R, T, B = 900, 460, 70, 170, 40, 50
    xs = [v for _, pts in series for v, _, _ in pts]
    ys = [p for _, pts in series for _, p, _ in pts] + [ref]
    x0, x1, y0, y1 = min(xs), max(xs), 0.0, min(max(ys), 120.0) * 1.05
    px = lambda x: L + (x - x0) / (x1 - x0) * (W - L - R)
    py = lambda y: T + (y1 - min(y, y1)) / (y1 - y0) * (H - T - B)
    svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" '
           'font-family="DejaVu Sans" font-size="12">',
           f'<text x="{(L + W - R) / 2}" y="22" text-anchor="middle" font-size="14">P_CT standing '
           '(EN 12299) against speed on the curve; open marks: comfort not valid</text>',
           f'<rect x="{L}" y="{T}" width="{W - L - R}" height="{H - T - B}" fill="none" stroke="#ccc"/>',
           f'<line x1="{L}" y1="{py(ref):.1f}" x2="{W - R}" y2="{py(ref):.1f}" stroke="#000" '
           'stroke-dasharray="6,4"/>',
           f'<text x="{W - R + 6}" y="{py(ref) + 4:.1f}">passive at design speed</text>']
    for k, (name, pts) in enumerate(series):
        c = colours[k % len(colours)]
        line = " ".join(f"{px(v):.1f},{py(p):.1f}" for v, p, _ in pts)
        svg.append(f'<polyline points="{line}" fill="none" stroke="{c}" stroke-width="2"/>')
        for v, p, ok in pts:
            fill = c if ok else "none"
            svg.append(f'<circle cx="{px(v):.1f}" cy="{py(p):.1f}" r="4" fill="{fill}" stroke="{c}"/>')
        svg.append(f'<text x="{W - R + 6}" y="{T + 30 + 18 * k}" fill="{c}">{name}</text>')
    for v in range(int(x0), int(x1) + 1, 10):
        svg.append(f'<text x="{px(v):.1f}" y="{H - B + 18}" text-anchor="middle">{v}</text>')
    svg.append(f'<text x="{(L + W - R) / 2}" y="{H - 10}" text-anchor="middle">speed (km/h)</text>')
    for p in range(0, int(y1) + 1, 20):
        svg.append(f'<text x="{L - 6}" y="{py(p) + 4:.1f}" text-anchor="end">{p}</text>')
    svg.append("</svg>")
    open(os.path.join(out, "speed-limit.svg"), "w").write("\n".join(svg) + "\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:])

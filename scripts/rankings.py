#!/usr/bin/env python3
"""Why the two P_CT evaluations rank the controllers differently, from a compare's runs.

Usage: rankings.py COMPARE_DIR  (writes COMPARE_DIR/rankings.md and rankings.svg)

The table splits each evaluation's P_CT into its two terms (the lateral term
max(A·ÿ_m + B·y⃛_m − C, 0) and the roll term D·φ̇_m^E, standing constants) from the peaks each
run's summary.json says it used. The figure draws each controller's absolute carbody roll
speed φ̇ = θ̇_v + θ̇_o from timeseries.csv, unfiltered and through a second-order Butterworth
low-pass at 0.3 Hz written here from its textbook bilinear form (independent of tiltsim's
filter), and the table gives this filter's peak beside the one tiltsim used.
"""

from __future__ import annotations

import csv
import json
import math
import os
import sys

RUNS = [("passive", "paper-passive", "#7f7f7f"), ("PI-drive", "pi-drive", "#1f77b4"),
        ("LQG", "paper-lqg", "#2ca02c"), ("MPC-KF", "paper-mpc", "#d62728")]
A, B, C, D, E = 28.54, 20.69, 11.1, 0.185, 2.283  # standing (model-notes, EN 12299)


def lowpass(x: list[float], fs: float, fc: float) -> list[float]:
    """Second-order Butterworth, bilinear transform with pre-warping, from rest at x[0]."""
    k = math.tan(math.pi * fc / fs)
    n = 1.0 / (1.0 + math.sqrt(2.0) * k + k * k)
    b0 = k * k * n
    b1, b2 = 2.0 * b0, b0
    a1 = 2.0 * (k * k - 1.0) * n
    a2 = (1.0 - math.sqrt(2.0) * k + k * k) * n
    y = [x[0]] * len(x)
    x1 = x2 = x[0]
    y1 = y2 = x[0]
    for i, v in enumerate(x):
        out = b0 * v + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2
        x2, x1, y2, y1 = x1, v, y1, out
        y[i] = out
    return y


def roll_speed(path: str) -> tuple[list[float], list[float]]:
    """Time and absolute roll speed (deg/s): θ̇_v plus the cant's rate by central difference."""
    t, dv, cant = [], [], []
    with open(path) as f:
        for r in csv.DictReader(f):
            t.append(float(r["time"]))
            dv.append(float(r["dtheta_v"]))
            cant.append(float(r["cant"]))
    n = len(t)
    dt = t[1] - t[0]
    rate = [(cant[min(i + 1, n - 1)] - cant[max(i - 1, 0)]) / ((min(i + 1, n - 1) - max(i - 1, 0)) * dt)
            for i in range(n)]
    return t, [math.degrees(a + b) for a, b in zip(dv, rate)]


def main(d: str) -> None:
    md = ["| controller | evaluation | ÿ_m (m/s²) | y⃛_m (m/s³) | φ̇_m (deg/s) | lateral term "
          "| roll term | P_CT standing (%) |", "|---|---|---|---|---|---|---|---|"]
    curves = []
    for label, run, colour in RUNS:
        c = json.load(open(os.path.join(d, run, "summary.json")))["comfort"]
        for key, name in (("p_ct_en12299", "EN 12299"), ("p_ct_paper", "paper's form")):
            p = c[key]
            lat = max(A * p["lat_acc_m_s2"] + B * p["jerk_m_s3"] - C, 0.0)
            roll = D * p["roll_speed_deg_s"] ** E
            md.append(f"| {label} | {name} | {p['lat_acc_m_s2']:.3f} | {p['jerk_m_s3']:.3f} "
                      f"| {p['roll_speed_deg_s']:.2f} | {lat:.2f} | {roll:.2f} "
                      f"| {p['standing_pct']:.2f} |")
        t, w = roll_speed(os.path.join(d, run, "timeseries.csv"))
        f = lowpass(w, 1.0 / (t[1] - t[0]), 0.3)
        curves.append((label, colour, t, w, f, c["p_ct_en12299"]["roll_speed_deg_s"]))
    md.append("")
    md.append("| controller | peak φ̇ unfiltered (deg/s) | peak φ̇, 0.3 Hz filter written "
              "independently (deg/s) | the filtered φ̇_m tiltsim used (deg/s) |")
    md.append("|---|---|---|---|")
    for label, _, _, w, f, used in curves:
        md.append(f"| {label} | {max(map(abs, w)):.2f} | {max(map(abs, f)):.2f} | {used:.2f} |")
    open(os.path.join(d, "rankings.md"), "w").write("\n".join(md) + "\n")

    # Four panels, one per controller: unfiltered (thin) and filtered (thick).
    W, PH, L, R, T, G = 900, 170, 70, 20, 40, 30
    H = T + len(curves) * (PH + G) + 20
    tmax = max(c[2][-1] for c in curves)
    ymax = max(max(map(abs, c[3])) for c in curves) * 1.05
    svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" '
           'font-family="DejaVu Sans" font-size="12">',
           f'<text x="{W / 2}" y="22" text-anchor="middle" font-size="14">Absolute carbody roll '
           'speed: unfiltered (thin) and 0.3 Hz low-pass (thick), deg/s</text>']
    for k, (label, colour, t, w, f, _) in enumerate(curves):
        top = T + k * (PH + G)
        px = lambda x: L + x / tmax * (W - L - R)
        py = lambda y: top + (ymax - y) / (2 * ymax) * PH
        svg.append(f'<rect x="{L}" y="{top}" width="{W - L - R}" height="{PH}" fill="none" '
                   'stroke="#ccc"/>')
        svg.append(f'<line x1="{L}" y1="{py(0):.1f}" x2="{W - R}" y2="{py(0):.1f}" stroke="#ddd"/>')
        for v in (-round(ymax), round(ymax)):
            svg.append(f'<text x="{L - 6}" y="{py(v) + 4:.1f}" text-anchor="end">{v}</text>')
        svg.append(f'<text x="{L + 8}" y="{top + 16}">{label}</text>')
        step = max(1, len(t) // 1500)
        for series, width in ((w, 0.8), (f, 2.2)):
            pts = " ".join(f"{px(t[i]):.1f},{py(series[i]):.1f}" for i in range(0, len(t), step))
            svg.append(f'<polyline points="{pts}" fill="none" stroke="{colour}" '
                       f'stroke-width="{width}"/>')
    for s in range(0, int(tmax) + 1, 2):
        x = L + s / tmax * (W - L - R)
        svg.append(f'<text x="{x:.1f}" y="{H - 6}" text-anchor="middle">{s} s</text>')
    svg.append("</svg>")
    open(os.path.join(d, "rankings.svg"), "w").write("\n".join(svg) + "\n")


if __name__ == "__main__":
    main(sys.argv[1])

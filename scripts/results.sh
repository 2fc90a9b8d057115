#!/usr/bin/env bash
# Regenerates docs/results.md: runs every comparison, sweep and design the document reports,
# then copies docs/results.in.md with each line `@include FILE` replaced by that file.
# About three minutes on two cores (the switched BLDC drive at 1 µs dominates).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
t="${CARGO_TARGET_DIR:-target}/release/tiltsim"
o=out/results
rm -rf "$o"
mkdir -p "$o"
"$t" compare scenarios/paper-passive.toml scenarios/paper-pi.toml scenarios/pi-drive.toml \
    scenarios/paper-lqg.toml scenarios/paper-mpc.toml scenarios/paper-mpc-hold.toml \
    scenarios/paper-mpc-preview.toml scenarios/paper-mpc-rho50.toml \
    --out "$o/paper" --transport in-process
"$t" compare scenarios/irregular-track.toml scenarios/pi-drive-irregular.toml \
    scenarios/lqg-irregular.toml scenarios/mpc-irregular.toml \
    --out "$o/irregular" --transport in-process
"$t" linearize scenarios/paper-pi.toml --design-pi --phase-margin 60 --gain-margin 6 --ti 0.25 \
    --out "$o/pi-design.json"
python3 - "$o/pi-design.json" > "$o/pi-design.md" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
rows = [("paper-pi (Table 3 gains)", d["pi_loop"]["kp"], d["pi_loop"]["ki"], d["pi_loop"]["margins"]),
        ("designed (pi-drive)", d["pi_design"]["kp"], d["pi_design"]["ki"], d["pi_design"]["margins"])]
print("| PI | K_p | K_i (1/s) | crossover (Hz) | phase margin (deg) | phase crossover (Hz) | gain margin (dB) |")
print("|---|---|---|---|---|---|---|")
for name, kp, ki, m in rows:
    print(f"| {name} | {kp:.4g} | {ki:.4g} | {m['crossover_hz']:.2f} | {m['phase_margin_deg']:.1f} | "
          f"{m['phase_crossover_hz']:.2f} | {m['gain_margin_db']:.1f} |")
PY
for c in paper-lqg paper-mpc pi-drive paper-pi; do
    "$t" sweep "scenarios/$c.toml" --samples 40 --seed 1 --out "$o/sweep-$c" -q
done
"$t" sweep scenarios/paper-lqg.toml --grid links.actuator_command.delay_ticks=0:100:20 \
    --out "$o/delay-lqg" -q
"$t" sweep scenarios/paper-mpc.toml --grid links.actuator_command.delay_ticks=0:100:20 \
    --out "$o/delay-mpc" -q
# Curving comfort against straight-track ride: each controller on the paper's curve and on
# 5 minutes of straight ERRI B176 high-level track; and the PI's proportional gain swept on
# both (K_i = K_p / 0.25 s kept: the integral time of the design), the front a tuner moves on.
"$t" compare scenarios/paper-passive.toml scenarios/pi-drive.toml scenarios/paper-lqg.toml \
    scenarios/paper-mpc.toml scenarios/straight-passive.toml scenarios/straight-pi-drive.toml \
    scenarios/straight-lqg.toml scenarios/straight-mpc.toml \
    --out "$o/trade-off" --transport in-process
python3 - "$o/trade-off/table.md" > "$o/trade-off/trade-off.md" <<'PY'
import sys
text = open(sys.argv[1]).read()
print(text[text.index("## Curving comfort against straight-track ride"):].split("\n", 2)[2].strip())
PY
for kp in 0.25 0.40 0.5708 0.80 1.10; do
    ki=$(python3 -c "print($kp / 0.25)")
    for sc in pi-drive straight-pi-drive; do
        "$t" run "scenarios/$sc.toml" --transport in-process --set controller.pi.kp=$kp \
            --set controller.pi.ki=$ki --out "$o/front/$sc-$kp" -q
    done
done
python3 - "$o/front" > "$o/front/front.md" <<'PY'
import json, sys, os
d = sys.argv[1]
rows = []
for kp in ["0.25", "0.40", "0.5708", "0.80", "1.10"]:
    c = json.load(open(os.path.join(d, f"pi-drive-{kp}", "summary.json")))["comfort"]
    s = json.load(open(os.path.join(d, f"straight-pi-drive-{kp}", "summary.json")))["comfort"]
    rows.append((float(kp), c["p_ct"]["standing"], c["lat_acc_peak_pct_g"],
                 s["ride"]["n_mv_lateral"], s["ride"]["tilt_error_rms_deg"],
                 s["ride"]["roll_acc_rms_rad_s2"]))
print("| K_p (K_i = K_p/0.25 s) | P_CT standing, curve (%) | lateral acceleration peak, curve (%g) "
      "| N_MV lateral part, straight | tilt error RMS, straight (deg) "
      "| roll acceleration RMS, straight (rad/s²) |")
print("|---|---|---|---|---|---|")
for r in rows:
    print(f"| {r[0]:.4g} | {r[1]:.2f} | {r[2]:.3f} | {r[3]:.3f} | {r[4]:.3f} | {r[5]:.3f} |")
# The front as a figure (SVG written here; tiltsim draws the per-controller one).
W, H, L, B, T, R = 900, 420, 80, 60, 40, 20
xs = [r[1] for r in rows]; ys = [r[3] for r in rows]
x0, x1 = min(xs), max(xs); y0, y1 = min(ys), max(ys)
px = lambda x: L + (x - x0 + 0.08 * (x1 - x0 + 1e-9)) / (1.16 * (x1 - x0 + 1e-9)) * (W - L - R)
py = lambda y: T + (y1 + 0.08 * (y1 - y0 + 1e-9) - y) / (1.16 * (y1 - y0 + 1e-9)) * (H - T - B)
svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="DejaVu Sans" font-size="12">',
       f'<rect width="{W}" height="{H}" fill="white"/>',
       f'<rect x="{L}" y="{T}" width="{W-L-R}" height="{H-T-B}" fill="none" stroke="black"/>',
       f'<text x="{L}" y="24" font-size="15" font-weight="bold">PI-drive: curving comfort against straight-track ride as K_p moves</text>',
       f'<text x="{(L+W-R)/2}" y="{H-15}" text-anchor="middle">P_CT standing on the curve, whole-run peaks (%)</text>',
       f'<text x="18" y="{(T+H-B)/2}" text-anchor="middle" transform="rotate(-90 18 {(T+H-B)/2})">N_MV lateral part on the straight</text>',
       '<polyline fill="none" stroke="#1f77b4" stroke-width="1.5" points="' + " ".join(f"{px(x):.1f},{py(y):.1f}" for x, y in zip(xs, ys)) + '"/>']
for r in rows:
    svg.append(f'<rect x="{px(r[1])-3.5:.1f}" y="{py(r[3])-3.5:.1f}" width="7" height="7" fill="#1f77b4"/>')
    svg.append(f'<text x="{px(r[1])+6:.1f}" y="{py(r[3])-6:.1f}">K_p {r[0]:.3g}</text>')
for v in sorted(set([round(x0, 1), round(x1, 1)])):
    svg.append(f'<text x="{px(v):.1f}" y="{H-B+18}" text-anchor="middle">{v}</text>')
for v in sorted(set([round(y0, 2), round(y1, 2)])):
    svg.append(f'<text x="{L-6}" y="{py(v)+4:.1f}" text-anchor="end">{v}</text>')
svg.append("</svg>")
open(os.path.join(d, "front.svg"), "w").write("\n".join(svg) + "\n")
PY
mkdir -p docs/figures
cp "$o/front/front.svg" docs/figures/pi-front.svg
cp "$o/trade-off/plots/trade_off.svg" docs/figures/trade-off.svg
while IFS= read -r line; do
    if [[ $line == "@include "* ]]; then
        cat "${line#@include }"
    else
        printf '%s\n' "$line"
    fi
done < docs/results.in.md > docs/results.md
echo "wrote docs/results.md from $o"

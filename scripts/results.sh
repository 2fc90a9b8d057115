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
python3 scripts/rankings.py "$o/paper"
"$t" compare scenarios/irregular-track.toml scenarios/pi-drive-irregular.toml \
    scenarios/lqg-irregular.toml scenarios/mpc-irregular.toml \
    --out "$o/irregular" --transport in-process
# The headline controllers on the whole car beside the half vehicle.
for sc in paper-passive pi-drive paper-lqg paper-mpc irregular-track pi-drive-irregular \
    lqg-irregular mpc-irregular; do
    for m in half full; do
        "$t" run "scenarios/$sc.toml" --set "vehicle.model=$m" --transport in-process \
            --no-plots --out "$o/full-car/$sc-$m" -q
    done
done
python3 scripts/full_car_table.py "$o/full-car" > "$o/full-car/table.md"
# The whole car's running safety against speed on the paper's curve, each tilting vehicle.
for v in passive pi-drive lqg mpc; do
    for kmh in 150 160 170 180 190 200 210 220 230 240; do
        "$t" run "scenarios/tilting-$v.toml" --set vehicle.model=full --set "track.speed_kmh=$kmh" \
            --transport in-process --no-plots --out "$o/full-car-speed/$v-$kmh" -q
    done
done
python3 scripts/full_car_speed.py "$o/full-car-speed" passive pi-drive lqg mpc \
    > "$o/full-car/speed.md"
# A tilting train's operating point: the tilting-* scenarios compared at 190 km/h, and each
# vehicle's speed swept on the paper's curve against the passive vehicle at its design speed.
"$t" compare scenarios/tilting-passive.toml scenarios/tilting-pi-drive.toml \
    scenarios/tilting-lqg.toml scenarios/tilting-mpc.toml --out "$o/tilting" --transport in-process
mkdir -p "$o/speed"
for v in passive pi-drive lqg mpc; do
    "$t" sweep "scenarios/tilting-$v.toml" --grid track.speed_kmh=150:210:5 \
        --out "$o/speed/tilting-$v" -q
done
python3 scripts/speed_limit.py "$o/speed" "$o/paper/paper-passive/summary.json" \
    "$o/speed/tilting-passive" "$o/speed/tilting-pi-drive" "$o/speed/tilting-lqg" \
    "$o/speed/tilting-mpc"
# Track localisation error: each controller with its position believed -20 to +20 m off.
for c in pi-drive paper-lqg paper-mpc; do
    "$t" sweep "scenarios/$c.toml" --grid controller.localisation.bias_m=-20:20:10 \
        --out "$o/localisation/$c" -q
done
python3 - "$o/localisation" > "$o/localisation/localisation.md" <<'PY'
import csv, os, sys
d = sys.argv[1]
runs = [("PI-drive", "pi-drive"), ("LQG", "paper-lqg"), ("MPC-KF", "paper-mpc")]
rows = {name: list(csv.DictReader(open(os.path.join(d, run, "samples.csv")))) for name, run in runs}
biases = [r["controller.localisation.bias_m"] for r in rows["LQG"]]
print("| bias (m) | " + " | ".join(f"{n}: P_CT EN 12299 / paper's form (%)" for n, _ in runs) + " |")
print("|---|" + "---|" * len(runs))
for i, b in enumerate(biases):
    cells = [f"{float(rows[n][i]['p_ct_en12299_standing_pct']):.2f} / "
             f"{float(rows[n][i]['p_ct_paper_standing_pct']):.2f}" for n, _ in runs]
    print(f"| {float(b):+.0f} | " + " | ".join(cells) + " |")
PY
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
# Passengers where they are: the curve's P_CT and the straight's ride at the centre of gravity
# and at each default position of [comfort] positions.
python3 - "$o/trade-off" > "$o/trade-off/positions.md" <<'PY'
import json, os, sys
d = sys.argv[1]
runs = [("passive", "paper-passive", "straight-passive"), ("PI-drive", "pi-drive", "straight-pi-drive"),
        ("LQG", "paper-lqg", "straight-lqg"), ("MPC-KF", "paper-mpc", "straight-mpc")]
load = lambda r: json.load(open(os.path.join(d, r, "summary.json")))["comfort"]
print("| controller | where | P_CT standing / seated on the curve, EN 12299 (%) "
      "| N_MV lateral part 6·a_YP95^Wd, straight | 6·a_ZP95^Wb from roll, straight "
      "| N_MV with the roll's vertical part, straight |")
print("|---|---|---|---|---|---|")
for name, curve, straight in runs:
    c, s = load(curve), load(straight)
    points = [("centre of gravity (1.52 m, centre line)", c["p_ct_en12299"], s["ride"])]
    for pc in c["positions"]:
        ps = next(p for p in s["positions"] if p["name"] == pc["name"])
        points.append((f"{pc['name']} ({pc['height_m']:.2f} m, {pc['offset_m']:+.1f} m)",
                       pc["p_ct_en12299"], ps["ride"]))
    for where, p, r in points:
        print(f"| {name} | {where} | {p['standing_pct']:.2f} / {p['seated_pct']:.2f} "
              f"| {6 * r['a_y_p95_wd_m_s2']:.3f} | {6 * r['a_z_p95_wb_m_s2']:.3f} | {r['n_mv_roll']:.3f} |")
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
    rows.append((float(kp), c["p_ct_en12299"]["standing_pct"], c["lat_acc_peak_pct_g"],
                 s["ride"]["n_mv_lateral"], s["ride"]["tilt_error_rms_deg"],
                 s["ride"]["roll_acc_rms_rad_s2"]))
print("| K_p (K_i = K_p/0.25 s) | P_CT standing (EN 12299), curve (%) | lateral acceleration peak, curve (%g) "
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
       f'<text x="{(L+W-R)/2}" y="{H-15}" text-anchor="middle">P_CT standing on the curve, EN 12299 (%)</text>',
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
# Free running: paper-mpc and pi-drive on their own clocks, on the machine as it is, with two
# CPU hogs, and with the controller given extra compute; each replayed in lock-step (the
# replay must give the free run's bytes), next to the lock-step run and to a lock-step run
# with the median extra ages declared as link delays.
f="$o/free"
mkdir -p "$f"
hogs=()
stop_hogs() { for p in "${hogs[@]}"; do kill "$p" 2>/dev/null || true; done; hogs=(); }
trap stop_hogs EXIT
for sc in paper-mpc pi-drive; do
    busy=0.03; [ "$sc" = pi-drive ] && busy=0.0008
    "$t" run "scenarios/$sc.toml" --transport in-process --out "$f/$sc-lock-step" -q
    "$t" run "scenarios/$sc.toml" --free-run --out "$f/$sc-quiet" -q
    for _ in 1 2; do yes > /dev/null & hogs+=($!); done
    "$t" run "scenarios/$sc.toml" --free-run --out "$f/$sc-hogs" -q || true
    stop_hogs
    "$t" run "scenarios/$sc.toml" --free-run --set run.controller_busy_wait_s=$busy \
        --out "$f/$sc-busy" -q
    for case in quiet hogs busy; do
        d="$f/$sc-$case"
        "$t" replay-timing "$d" --no-plots -q
        if cmp -s "$d/timeseries.csv" "$d/replay-timing/timeseries.csv"; then
            echo identical > "$d/replay.txt"
        else
            echo DIFFERS > "$d/replay.txt"
        fi
        # Each link's median lag behind lock-step Gauss-Seidel, as a declared delay: for the
        # command, the ticks from a controller step to the first actuator step that read its
        # output; for the measurement and the bar angle, the input's age.
        python3 - "$d" > "$d/equivalent.toml" <<'PY'
import csv, statistics, sys
d = sys.argv[1]
lines = open(f"{d}/timing.csv").read().splitlines()
first = {}
lag = {"actuator_command": [], "measurement": [], "bar_angle": []}
for r in csv.DictReader(lines[1:]):
    step = int(r["step"])
    if r["role"] == "actuator":
        c = int(r["from_controller"])
        if c >= 0:
            first[c] = min(first.get(c, step), step)
    elif r["role"] == "controller":
        lag["measurement"].append(int(r["age_plant"]))
    else:
        lag["bar_angle"].append(int(r["age_actuator"]))
lag["actuator_command"] = [k - c for c, k in first.items()]
for link, xs in lag.items():
    print(f"[links.{link}]\ndelay_ticks = {max(0, round(statistics.median(xs)))}\n")
PY
        cat "$f/$sc-lock-step/scenario.toml" > "$d/equivalent-scenario.toml"
        python3 - "$d/equivalent-scenario.toml" "$d/equivalent.toml" <<'PY'
import sys, tomllib
base = open(sys.argv[1]).read()
add = tomllib.loads(open(sys.argv[2]).read())
doc = tomllib.loads(base)
# The lock-step run's resolved scenario has every link written out: set only the delays.
lines = base.splitlines()
out = []
section = None
for line in lines:
    s = line.strip()
    if s.startswith("[") and s.endswith("]"):
        section = s.strip("[]")
    out.append(line)
    if section and section.startswith("links.") and s.startswith("delay_ticks"):
        name = section.split(".", 1)[1]
        if name in add["links"]:
            out[-1] = f"delay_ticks = {add['links'][name]['delay_ticks']}"
open(sys.argv[1], "w").write("\n".join(out) + "\n")
PY
        "$t" run "$d/equivalent-scenario.toml" --transport in-process --out "$d/equivalent" -q
    done
done
stop_hogs
python3 - "$f" > "$f/free.md" <<'PY'
import json, os, sys
f = sys.argv[1]
def load(p):
    return json.load(open(p))
def raised(flags):
    return ", ".join(k for k, v in flags.items() if isinstance(v, dict) and v.get("raised")) or "clear"
print("| scenario | case | P_CT standing, EN 12299 (%) | peak lateral acc. (%g) | flags | command age p50 / p99 / max (ticks) "
      "| measurement age p50 / p99 / max | plant late steps | plant lateness max (ms) | not real-time | replay "
      "| declared delays (command, measurement, bar angle; ticks) | lock-step with them: P_CT standing, EN 12299 (%) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for sc in ["paper-mpc", "pi-drive"]:
    ref = load(f"{f}/{sc}-lock-step/summary.json")
    c = ref["comfort"]
    print(f"| {sc} | lock-step | {c['p_ct_en12299']['standing_pct']:.2f} | {c['lat_acc_peak_pct_g']:.2f} "
          f"| {raised(ref['flags'])} | | | | | | | | |")
    for case, label in [("quiet", "free, machine as it is"), ("hogs", "free, two CPU hogs"),
                        ("busy", "free, controller +extra compute")]:
        d = f"{f}/{sc}-{case}"
        s = load(f"{d}/summary.json")
        p = load(f"{d}/perf.json")["free_run"]
        ages = p["input_age_ticks"]
        a = lambda k: f"{ages[k]['p50']} / {ages[k]['p99']} / {ages[k]['max']}"
        pl = p["participants"]["plant"]
        eq = load(f"{d}/equivalent/summary.json")["comfort"]["p_ct_en12299"]["standing_pct"]
        delays = [l.split("=")[1].strip() for l in open(f"{d}/equivalent.toml") if l.startswith("delay_ticks")]
        c = s["comfort"]
        print(f"| {sc} | {label} | {c['p_ct_en12299']['standing_pct']:.2f} | {c['lat_acc_peak_pct_g']:.2f} "
              f"| {raised(s['flags'])} | {a('actuator_command')} | {a('measurement')} "
              f"| {pl['late_starts']} | {pl['start_lateness_us']['max'] / 1000:.1f} "
              f"| {'yes' if s['flags']['not_real_time']['raised'] else 'no'} | {open(f'{d}/replay.txt').read().strip()} | {', '.join(delays)} | {eq:.2f} |")
PY
# A whole line: the synthetic winding-valley line with each vehicle on its speed profile
# (the passive one conventional, the tilt controllers tilting), and the compensation trade-off.
"$t" route routes/winding-valley.csv scenarios/line-passive.toml scenarios/line-pi-drive.toml \
    scenarios/line-lqg.toml scenarios/line-mpc.toml --out "$o/route" -q
"$t" route routes/winding-valley.csv scenarios/line-pi-drive.toml scenarios/line-lqg.toml \
    scenarios/line-mpc.toml --rho 0.3,0.55,0.7,1.0 --out "$o/route-rho" -q
python3 scripts/route_tables.py "$o/route" "$o/route-rho"
mkdir -p docs/figures
cp "$f/paper-mpc-hogs/plots/timing_input_age.svg" docs/figures/free-run-input-age.svg
cp "$f/paper-mpc-hogs/plots/timing_lateness.svg" docs/figures/free-run-lateness.svg
cp "$o/front/front.svg" docs/figures/pi-front.svg
cp "$o/trade-off/plots/trade_off.svg" docs/figures/trade-off.svg
cp "$o/paper/rankings.svg" docs/figures/rankings-roll-speed.svg
cp "$o/speed/speed-limit.svg" docs/figures/speed-limit.svg
cp "$o/route/plots/route_p_ct.svg" docs/figures/route-p-ct.svg
cp "$o/route/plots/route_speed.svg" docs/figures/route-speed.svg
cp "$o/route-rho/plots/route_trade_off.svg" docs/figures/route-trade-off.svg
while IFS= read -r line; do
    if [[ $line == "@include "* ]]; then
        cat "${line#@include }"
    else
        printf '%s\n' "$line"
    fi
done < docs/results.in.md > docs/results.md
echo "wrote docs/results.md from $o"

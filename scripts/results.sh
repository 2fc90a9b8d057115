#!/usr/bin/env bash
# Regenerates docs/results.md: runs every comparison, sweep and design the document reports,
# then copies docs/results.in.md with each line `@include FILE` replaced by that file.
# About three minutes on two cores (the switched BLDC drive at 1 µs dominates).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
t=target/release/tiltsim
o=out/results
rm -rf "$o"
mkdir -p "$o"
$t compare scenarios/paper-passive.toml scenarios/paper-pi.toml scenarios/pi-drive.toml \
    scenarios/paper-lqg.toml scenarios/paper-mpc.toml scenarios/paper-mpc-hold.toml \
    scenarios/paper-mpc-preview.toml scenarios/paper-mpc-rho50.toml \
    --out "$o/paper" --transport in-process
$t compare scenarios/irregular-track.toml scenarios/pi-drive-irregular.toml \
    scenarios/lqg-irregular.toml scenarios/mpc-irregular.toml \
    --out "$o/irregular" --transport in-process
$t linearize scenarios/paper-pi.toml --design-pi --phase-margin 60 --gain-margin 6 --ti 0.25 \
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
    $t sweep "scenarios/$c.toml" --samples 40 --seed 1 --out "$o/sweep-$c" -q
done
$t sweep scenarios/paper-lqg.toml --grid links.actuator_command.delay_ticks=0:100:20 \
    --out "$o/delay-lqg" -q
$t sweep scenarios/paper-mpc.toml --grid links.actuator_command.delay_ticks=0:100:20 \
    --out "$o/delay-mpc" -q
while IFS= read -r line; do
    if [[ $line == "@include "* ]]; then
        cat "${line#@include }"
    else
        printf '%s\n' "$line"
    fi
done < docs/results.in.md > docs/results.md
echo "wrote docs/results.md from $o"

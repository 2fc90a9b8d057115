#!/usr/bin/env python3
"""Writes a synthetic line as a route file for `tiltsim route`: NAME.csv with N curves.

Usage: synthetic_route.py OUT.csv --curves N --seed S --line-kmh CONV,TILT
                          --radius LO,HI --straight LO,HI

The line is made up, not surveyed: straights and curves alternate; each curve's radius is
drawn log-uniformly in [LO, HI] m and signed at random; its cant is the one that balances
60 % of the conventional line speed's lateral acceleration, 11.8·(0.6·V)²/R mm (V in km/h),
rounded to 5 mm and held within 20-160 mm; its transitions are long enough for a cant rate
of 55 mm/s at the tilting speed limit the cant deficiency allows (and at least 60 m), in 10 m
steps, and cycle through the clothoid, the cosine and Bloss shapes; its arc is 150-900 m.
The sections carry the line speeds, so the cant deficiency sets the speed on most curves; every
seventh curve has a local limit of its own, 10 km/h under the speed its cant deficiency
allows in each running (rounded down to 5 km/h), as a junction or a station would impose. Everything is drawn from
Python's Mersenne Twister seeded with S, so the same arguments write the same file.
"""

import argparse
import math
import random

G = 9.81
SHAPES = ["clothoid", "cosine", "bloss"]


def cd_speed_kmh(radius: float, cant: float, cd: float) -> float:
    return 3.6 * math.sqrt(G * radius * (cant + cd) / 1500.0)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("out")
    p.add_argument("--curves", type=int, required=True)
    p.add_argument("--seed", type=int, required=True)
    p.add_argument("--line-kmh", required=True)
    p.add_argument("--radius", required=True)
    p.add_argument("--straight", required=True)
    p.add_argument("--title", default="")
    a = p.parse_args()
    conv, tilt = (float(x) for x in a.line_kmh.split(","))
    rlo, rhi = (float(x) for x in a.radius.split(","))
    slo, shi = (float(x) for x in a.straight.split(","))
    rng = random.Random(a.seed)
    rows = []
    s = 0.0

    def straight(length: float) -> None:
        nonlocal s
        rows.append(f"{s:.0f},{length:.0f},,,,,{conv:.0f},{tilt:.0f}")
        s += length

    straight(round(rng.uniform(2000, 3000), -1))
    for k in range(a.curves):
        r = round(math.exp(rng.uniform(math.log(rlo), math.log(rhi))), -1)
        sign = rng.choice([-1, 1])
        cant = 11.8 * (0.6 * conv) ** 2 / r
        cant = min(160.0, max(20.0, 5.0 * round(cant / 5.0)))
        v_tilt = min(tilt, cd_speed_kmh(r, cant, 275.0))
        lt = max(60.0, 10.0 * math.ceil(v_tilt / 3.6 * cant / 55.0 / 10.0))
        local = k % 7 == 6
        v_conv = 5.0 * math.floor((cd_speed_kmh(r, cant, 150.0) - 10.0) / 5.0) if local else conv
        v_tilt = 5.0 * math.floor((v_tilt - 10.0) / 5.0) if local else tilt
        arc = round(rng.uniform(150, 900), -1)
        length = 2 * lt + arc
        rows.append(
            f"{s:.0f},{length:.0f},{sign * r:.0f},{cant:.0f},{lt:.0f},{SHAPES[k % 3]},{v_conv:.0f},{v_tilt:.0f}"
        )
        s += length
        straight(round(rng.uniform(slo, shi), -1))
    head = [
        f"# {a.title}" if a.title else "# A synthetic line",
        "# SYNTHETIC: made up by scripts/synthetic_route.py, not a surveyed railway.",
        f"# synthetic_route.py {a.out.split('/')[-1]} --curves {a.curves} --seed {a.seed} "
        f"--line-kmh {a.line_kmh} --radius {a.radius} --straight {a.straight}",
        "chainage_m,length_m,radius_m,cant_mm,transition_m,shape,vmax_conventional_kmh,vmax_tilting_kmh",
    ]
    with open(a.out, "w") as f:
        f.write("\n".join(head + rows) + "\n")


if __name__ == "__main__":
    main()

"""A tilt-control study as a notebook makes it, with the `tiltsim` Python package.

1. The paper's controllers on its track (Table 4): passive, PI (tuned for the drive: the
   paper's own gains make it oscillate), LQG and MPC, their ride
   comfort side by side with the ideal tilt, and the lateral acceleration the passengers
   feel through the curve (figure `controllers.png`).
2. The paper's Fig. 21: the LQG tilt under ±22 % on masses, inertias and suspension (a Monte
   Carlo sweep): the median and the 5-95 % band of the lateral acceleration over the run
   (figure `fig21_robustness.png`).

Run from the repository's root, in the environment the package is installed in:

    python examples/notebook_study.py --out out/notebook-study

Each cell of a notebook would hold one of the blocks of `main`. The script ends with an error
if a result the figures rely on is not valid (a validity flag raised on an active controller
or a failed sample).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import tiltsim  # noqa: E402

G = 9.80665
CONTROLLERS = {
    "passive": "scenarios/paper-passive.toml",
    "PI": "scenarios/pi-drive.toml",
    "LQG": "scenarios/paper-lqg.toml",
    "MPC-KF": "scenarios/paper-mpc.toml",
}


def controllers(out: Path) -> dict[str, tiltsim.Result]:
    """The four controllers on the paper's track, one run each."""
    runs = {name: tiltsim.run(path, transport="in-process") for name, path in CONTROLLERS.items()}
    fig, (ax_acc, ax_tilt) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for name, r in runs.items():
        ax_acc.plot(r.time, 100 * r.lat_acc / G, label=name, linewidth=1)
        ax_tilt.plot(r.time, np.degrees(r.theta_v), label=name, linewidth=1)
    ax_acc.set_ylabel("lateral acceleration felt (%g)")
    ax_tilt.set_ylabel("carbody roll θ_v (deg)")
    ax_tilt.set_xlabel("time (s)")
    ax_acc.legend(loc="upper right", fontsize="small")
    for ax in (ax_acc, ax_tilt):
        ax.grid(alpha=0.3)
    fig.suptitle("Tilt controllers on the paper's track")
    fig.tight_layout()
    fig.savefig(out / "controllers.png", dpi=120)
    plt.close(fig)
    for name, r in runs.items():
        p = r.comfort["p_ct_en12299"]["standing_pct"]
        flags = ", ".join(r.raised_flags) or "none"
        print(f"{name:8s} P_CT standing (EN 12299) {p:6.2f} %   flags: {flags}")
    return runs


def table4(out: Path) -> object:
    """The comparison laid out like the paper's Table 4 (a pandas DataFrame)."""
    table = tiltsim.compare(list(CONTROLLERS.values()), transport="in-process")
    # Tidy: one row per metric and run; the whole-run metrics (not those at a passenger
    # position) pivot into a column per controller, the ideal tilt beside them.
    whole = table[table["position"] == ""]
    t4 = whole.pivot_table(index="metric", columns="controller", values="value",
                           aggfunc="first", sort=False)
    t4.to_csv(out / "table4.csv")
    print(t4.to_string(max_colwidth=24))
    return t4


def fig21(out: Path, samples: int) -> object:
    """The LQG tilt under ±22 % parameter spread: the lateral acceleration's band."""
    table, series = tiltsim.sweep("scenarios/paper-lqg.toml", samples=samples, spread=0.22,
                                  seed=1, series=True)
    failed = table[table["status"] != "completed"]
    if len(failed):
        raise SystemExit(f"{len(failed)} samples failed:\n{failed[['sample_id', 'status']]}")
    wide = series.pivot(index="time", columns="sample_id", values="lat_acc") * 100 / G
    q = wide.quantile([0.05, 0.5, 0.95], axis=1).T
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.fill_between(q.index, q[0.05], q[0.95], alpha=0.3, label="5-95 % of samples")
    ax.plot(q.index, q[0.5], linewidth=1, label="median")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("lateral acceleration felt (%g)")
    ax.set_title(f"LQG tilt, ±22 % on masses, inertias and suspension ({samples} samples)")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize="small")
    fig.tight_layout()
    fig.savefig(out / "fig21_robustness.png", dpi=120)
    plt.close(fig)
    spread = table["p_ct_en12299_standing_pct"].quantile([0.05, 0.5, 0.95])
    print(f"LQG P_CT standing over {samples} samples: p5 {spread[0.05]:.2f} %, "
          f"median {spread[0.5]:.2f} %, p95 {spread[0.95]:.2f} %")
    return table


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="out/notebook-study", help="directory for the figures")
    ap.add_argument("--samples", type=int, default=16, help="Monte Carlo samples of Fig. 21")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = controllers(out)
    table4(out)
    fig21(out, a.samples)
    bad = [n for n, r in runs.items() if n != "passive" and not r.valid]
    if bad:
        raise SystemExit(f"not valid as a comfort result: {', '.join(bad)}")
    print(f"wrote {out}/controllers.png, fig21_robustness.png, table4.csv")


if __name__ == "__main__":
    main()

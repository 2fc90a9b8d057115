"""What the Python package adds to a run: tiltsim.run's time against the library's own time in
the same call and the lock-step loop's, alternating with the `tiltsim run` process.

    python scripts/python-overhead.py [SCENARIO] [--repeat N]   (from the repository's root,
                                                                 in the package's environment)
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import tiltsim


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("scenario", nargs="?", default="scenarios/paper-mpc.toml")
    ap.add_argument("--repeat", type=int, default=10)
    ap.add_argument("--cli", default="target/release/tiltsim", help="the tiltsim executable")
    a = ap.parse_args()
    tiltsim.run(a.scenario, transport="in-process")  # caches warm
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(a.repeat):
            t = time.perf_counter()
            subprocess.run([a.cli, "run", a.scenario, "--transport", "in-process", "--out",
                            tmp, "--quiet"], check=True)
            cli = time.perf_counter() - t
            cli_loop = json.loads((Path(tmp) / "summary.json").read_text())["wall_time_s"]
            t = time.perf_counter()
            r = tiltsim.run(a.scenario, transport="in-process")
            call = time.perf_counter() - t
            rows.append((call, r.library_s, r.summary["wall_time_s"], cli, cli_loop))
    call, lib, loop, cli, cli_loop = (statistics.median(c) for c in zip(*rows))
    print(f"medians of {a.repeat}, alternating, {a.scenario} in one process:")
    print(f"  tiltsim.run (no files)        {call:.4f} s")
    print(f"    the library                 {lib:.4f} s")
    print(f"    the lock-step loop          {loop:.4f} s")
    print(f"    the Python side             {call - lib:.4f} s = {100 * (call - lib) / loop:.2f} % of the loop")
    print(f"  tiltsim run (process, files)  {cli:.4f} s (loop {cli_loop:.4f} s)")


if __name__ == "__main__":
    main()

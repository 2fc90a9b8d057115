#!/usr/bin/env python3
"""Concurrent IPC runs on one machine: wall time per run and in total.

    scripts/concurrent.py [--tiltsim PATH] [--runs N] [--hogs H] [--out DIR] -- RUN ARGS...

Starts H CPU hogs (`yes > /dev/null`), then N `tiltsim run RUN ARGS... --out DIR/rK -q` at
once, waits for all, stops the hogs (by pid) and prints one JSON line: the runs' wall times
(each process's, from its start to its exit), their median, the total, the lock-step loops'
wall times (`summary.json` -> `wall_time_s`), how many completed,
the placements the runs chose (`summary.json` -> `timing.placement.reason`) and the load
average before and after. docs/performance.md ("Many runs on one machine") gives the
commands and figures.
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import time


def load():
    with open("/proc/loadavg") as f:
        return float(f.read().split()[0])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tiltsim", default="target/release/tiltsim")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--hogs", type=int, default=0)
    ap.add_argument("--out", default="out/concurrent")
    ap.add_argument("args", nargs=argparse.REMAINDER)
    a = ap.parse_args()
    args = [x for x in a.args if x != "--"]
    shutil.rmtree(a.out, ignore_errors=True)
    os.makedirs(a.out)
    hogs = [
        subprocess.Popen(["yes"], stdout=subprocess.DEVNULL) for _ in range(a.hogs)
    ]
    try:
        load0 = load()
        t0 = time.monotonic()
        procs = []
        for k in range(a.runs):
            out = os.path.join(a.out, f"r{k}")
            p = subprocess.Popen([a.tiltsim, "run", *args, "--out", out, "-q"])
            procs.append((p, time.monotonic(), out))
        walls, loops, ok, reasons = [], [], 0, {}
        pending = list(procs)
        ends = {}
        while pending:
            for item in list(pending):
                p, _, out = item
                if p.poll() is not None:
                    ends[out] = time.monotonic()
                    pending.remove(item)
            time.sleep(0.01)
        total = time.monotonic() - t0
        for p, start, out in procs:
            walls.append(ends[out] - start)
            ok += p.returncode == 0
            try:
                with open(os.path.join(out, "summary.json")) as f:
                    sm = json.load(f)
                loops.append(sm["wall_time_s"])
                pl = sm["timing"].get("placement") or {}
                r = pl.get("reason", "none") + "/" + pl.get("wait", "?")
            except (OSError, ValueError, KeyError):
                r = "no summary"
            reasons[r] = reasons.get(r, 0) + 1
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    print(
        json.dumps(
            {
                "runs": a.runs,
                "hogs": a.hogs,
                "completed": ok,
                "wall_median_s": round(statistics.median(walls), 3),
                "wall_min_s": round(min(walls), 3),
                "wall_max_s": round(max(walls), 3),
                "total_s": round(total, 3),
                "loop_median_s": round(statistics.median(loops), 3) if loops else None,
                "loop_max_s": round(max(loops), 3) if loops else None,
                "placements": reasons,
                "load_before": load0,
                "load_after": load(),
            }
        )
    )


if __name__ == "__main__":
    main()

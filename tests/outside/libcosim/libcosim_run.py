"""Runs an SSP system with libcosim (the Open Simulation Platform's master, through libcosimpy),
a master tiltsim did not write.

    python libcosim_run.py SSD STEPS OUT_CSV

Loads SSD (a SystemStructure.ssd, or the directory holding it) as it is, with libcosim's
fixed-step (Jacobi) algorithm and the steps the file gives, takes STEPS base steps and writes,
after each, every output of every FMU as libcosim's last-value observer holds it: one row per
step, `step` (1 after the first step) then one column `COMPONENT.VARIABLE` per output, reals in
Python's shortest round-trip form (exact). Prints one JSON object: the components, the base
steps taken and the columns written. Exits non-zero when libcosimpy cannot be imported, the
file does not load or a step fails.
"""
import csv
import json
import sys

from libcosimpy.CosimEnums import CosimVariableCausality, CosimVariableType
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver


def outputs_of(execution, index):
    """(name, reference, type) of each output of the slave at `index`."""
    found = []
    for v in execution.slave_variables(index):
        if CosimVariableCausality(v.causality) == CosimVariableCausality.OUTPUT:
            found.append((v.name.decode(), v.reference, CosimVariableType(v.type)))
    return found


def main():
    ssd, steps, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    log_output_level(CosimLogLevel.WARNING)
    execution = CosimExecution.from_ssp_file(ssd)
    observer = CosimObserver.create_last_value()
    if not execution.add_observer(observer=observer):
        sys.exit("libcosim: the last-value observer was not added")
    slaves = sorted((s.name.decode(), s.index) for s in execution.slave_infos())
    reads = []
    columns = []
    for name, index in slaves:
        outs = outputs_of(execution, index)
        reals = [(n, r) for n, r, t in outs if t == CosimVariableType.REAL]
        ints = [(n, r) for n, r, t in outs if t == CosimVariableType.INTEGER]
        reads.append((index, reals, ints))
        columns += [f"{name}.{n}" for n, _ in reals] + [f"{name}.{n}" for n, _ in ints]
    with open(out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["step"] + columns)
        for k in range(1, steps + 1):
            if not execution.step():
                sys.exit(f"libcosim: step {k} failed")
            row = [k]
            for index, reals, ints in reads:
                if reals:
                    row += [repr(v) for v in observer.last_real_values(index, [r for _, r in reals])]
                if ints:
                    row += [str(v) for v in observer.last_integer_values(index, [r for _, r in ints])]
            w.writerow(row)
    print(json.dumps({"components": [n for n, _ in slaves], "steps": steps, "columns": columns}))


if __name__ == "__main__":
    main()

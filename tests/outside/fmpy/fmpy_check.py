"""Checks a tiltsim FMU with FMPy, a client tiltsim did not write.

    python fmpy_check.py FMU RUN_MCAP ROLE

1. FMPy's validation of the FMU (its list of problems must be empty), and the direct
   dependencies of each output as FMPy reads them from ModelStructure (null where none are
   declared);
2. FMPy's own co-simulation of the FMU (fmpy.simulate_fmu), fed the inputs the participant
   received in a tiltsim run (RUN_MCAP's /ROLE/in channel), stepping with the participant's
   period (the ticks between its recorded requests, of the FMU's base tick, its stepSize);
3. every output FMPy recorded compared with the reply the participant gave in that run
   (/ROLE/out): the reply to request k is the output at the next communication point.

Prints one JSON object: problems, dependencies, steps, compared, mismatches, first mismatch, and the largest
|difference| per field.
"""
import json
import sys

import numpy as np
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu
from mcap.reader import make_reader

STATE = ["y_v", "theta_v", "y_b", "theta_b", "dy_v", "dtheta_v", "dy_b", "dtheta_b", "theta_r"]


# Recorded fields whose FMU variable has another name: the actuator FMU's own output `limits`
# is `actuator_limits` in the recording, as in timeseries.csv; the controller FMU's input `t`
# (the time of the plant sample it is given, not a master's own `time`) is `time` there.
RENAMED = {"actuator_limits": "limits", "time": "t"}


def fmu_name(field):
    """The FMU variable of a recorded field (the plant's state vector x is recorded by name)."""
    if field in STATE:
        return f"x[{STATE.index(field)}]"
    return RENAMED.get(field, field)


def main():
    fmu, mcap_path, role = sys.argv[1:4]
    problems = validate_fmu(fmu)
    md = read_model_description(fmu)
    messages = {"in": [], "out": []}
    with open(mcap_path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(
            topics=[f"/{role}/in", f"/{role}/out"]
        ):
            messages[channel.topic.rsplit("/", 1)[1]].append(json.loads(message.data))
    ins, outs = messages["in"], messages["out"]
    inputs = [k for k in ins[0] if k != "step"]
    step = float(md.defaultExperiment.stepSize) * (ins[1]["step"] - ins[0]["step"])
    # FMPy's communication points are start_time + n * step: the input's times are built with
    # the same arithmetic, so each request is applied exactly at its own point.
    signal = np.zeros(
        len(ins), dtype=[("time", np.float64)] + [(fmu_name(n), np.float64) for n in inputs]
    )
    for n, m in enumerate(ins):
        signal[n] = tuple([0.0 + n * step] + [m[k] for k in inputs])
    fields = [k for k in outs[0] if k != "step"]
    result = simulate_fmu(
        fmu,
        stop_time=len(ins) * step,
        step_size=step,
        output_interval=step,
        input=signal,
        fmi_type="CoSimulation",
        output=[fmu_name(f) for f in fields],
    )
    compared = mismatches = 0
    first = None
    largest = {f: 0.0 for f in fields}
    # The plant's and the actuator's recorded outputs begin with those at t = 0 (FMPy's row 0)
    # and the n-th step's outputs hold at its end (row n + 1); the controller's answer of its
    # n-th step is recorded at the step's start and reaches FMPy's output at the next
    # communication point (row n + 1).
    first_row = 1 if role == "controller" else 0
    for n, m in enumerate(outs):
        row = result[n + first_row]
        for f in fields:
            want = m[f]
            got = float(row[fmu_name(f)])
            compared += 1
            if want is None or got != float(want):
                mismatches += 1
                if want is not None:
                    largest[f] = max(largest[f], abs(got - float(want)))
                if first is None:
                    first = {"step": m["step"], "field": f, "recorded": want, "fmpy": got}
    dependencies = {
        u.variable.name: None if u.dependencies is None else [v.name for v in u.dependencies]
        for u in md.outputs
    }
    print(json.dumps({
        "problems": [str(p) for p in problems],
        "dependencies": dependencies,
        "steps": len(result) - 1,
        "requests": len(ins),
        "compared": compared,
        "mismatches": mismatches,
        "first": first,
        "largest": largest,
        "inputs": inputs,
    }))


if __name__ == "__main__":
    main()

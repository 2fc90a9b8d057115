"""Runs tiltsim's three FMUs in FMPy's container FMU (fmpy.container_fmu), a master tiltsim did
not write.

    python fmpy_container.py WORK_DIR STEP_S STEPS OUT_CSV ROLE=FMU ...

Builds WORK_DIR/Container.fmu (FMI 3.0) from the FMUs given, their inputs connected to the
outputs that feed them (the same wiring as `tiltsim export-ssp`: plant.delta_a from
actuator.delta_a; actuator.delta_a_cmd from controller.delta_a_cmd and actuator.psi from
plant.psi; controller.t, .s, .theta_v_meas from the plant), every output of every FMU exposed
as a container output `ROLE.VARIABLE`, a fixed step of STEP_S s. Then FMPy simulates the
container for STEPS steps of STEP_S s and writes every output after each step: one row per
step, `step` (1 after the first) then the columns, reals in Python's shortest round-trip form
(exact). Prints one JSON object: the steps and the columns written.
"""
import csv
import json
import sys
from pathlib import Path

from fmpy import read_model_description, simulate_fmu
from fmpy.container_fmu import Configuration
from fmpy.container_fmu.cli import create_container_fmu
from fmpy.container_fmu.config import Component, Connection
from fmpy.model_description import CoSimulation, DefaultExperiment, ModelDescription, ModelVariable

WIRING = [
    ("actuator", "delta_a", "plant", "delta_a"),
    ("controller", "delta_a_cmd", "actuator", "delta_a_cmd"),
    ("plant", "psi", "actuator", "psi"),
    ("plant", "t", "controller", "t"),
    ("plant", "s", "controller", "s"),
    ("plant", "theta_v_meas", "controller", "theta_v_meas"),
]


def main():
    work, step, steps, out = Path(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    fmus = dict(a.split("=", 1) for a in sys.argv[5:])
    components = {}
    for role, path in fmus.items():
        md = read_model_description(path)
        components[role] = Component(name=role, filename=Path(path), modelDescription=md)
    variables = {r: {v.name: v for v in c.modelDescription.modelVariables} for r, c in components.items()}
    connections = [
        Connection(
            startElement=components[a],
            startConnectors=[variables[a][o]],
            endElement=components[b],
            endConnectors=[variables[b][i]],
        )
        for a, o, b, i in WIRING
    ]
    container = ModelDescription(
        fmiVersion="3.0",
        modelName="tiltsim",
        instantiationToken="{d6a3a7e0-6c1b-4f7e-9d61-2f6a61c0a5e1}",
        coSimulation=CoSimulation(modelIdentifier="container_fmu", fixedInternalStepSize=step),
        defaultExperiment=DefaultExperiment(startTime="0", stopTime=str(step * steps), stepSize=str(step)),
    )
    # The container's value reference 0 is its time; its variables follow from 1 in order.
    container.modelVariables.append(
        ModelVariable(name="time", causality="independent", variability="continuous", type="Float64")
    )
    mappings = {}
    columns = []
    for role, c in components.items():
        for v in c.modelDescription.modelVariables:
            if v.causality != "output":
                continue
            name = f"{role}.{v.name}"
            outer = ModelVariable(
                name=name,
                causality="output",
                variability=v.variability,
                type=v.type,
                initial="calculated",
            )
            container.modelVariables.append(outer)
            mappings[outer] = [(c, v)]
            columns.append(name)
    config = Configuration(
        parallelDoStep=False,
        modelDescription=container,
        components=list(components.values()),
        connections=connections,
        variableMappings=mappings,
    )
    (work / "unzipped").mkdir(parents=True, exist_ok=True)
    fmu = work / "Container.fmu"
    create_container_fmu(config, work / "unzipped", fmu)
    result = simulate_fmu(
        str(fmu),
        stop_time=step * steps,
        step_size=step,
        output_interval=step,
        output=columns,
        fmi_type="CoSimulation",
    )
    with open(out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["step"] + columns)
        for k in range(1, len(result)):
            w.writerow([k] + [repr(v.item()) for v in (result[c][k] for c in columns)])
    print(json.dumps({"steps": len(result) - 1, "columns": columns}))


if __name__ == "__main__":
    main()

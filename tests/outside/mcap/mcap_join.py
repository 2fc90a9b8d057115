"""Joins every channel of a tiltsim run.mcap with the run's timeseries.csv on `step`, as
docs/studies.md ("Joining a recording and the table") says a reader may, and prints per
channel what disagrees, as JSON:

* `messages`: the channel's messages;
* `values`: the field values compared with a cell of the table;
* `differ`: the values (and log times, which must be step·dt) that differ;
* `mismatches`: the first few `[step, field, recorded, column, table]` that differ (a field
  left out of a message, as a non-finite value is, must meet a non-finite cell).

Every field of a data channel is a column of the row `step` (`JOIN`), but for the few that
docs/studies.md places in the row before (`BEFORE`): the controller's request instant and a
link's sent value where the sender's output is that of the tick's start. `/events` join on
`step` with the row's `time`; `/summary` and `/perf` have no step and are only counted.

    python mcap_join.py RUN.mcap TIMESERIES.csv MASTER
"""

import csv
import json
import math
import sys

from mcap.reader import make_reader

PLANT = ["time", "s", "curvature", "cant", "y_v", "theta_v", "y_b", "theta_b", "dy_v",
         "dtheta_v", "dy_b", "dtheta_b", "theta_r", "psi", "lat_acc", "theta_v_meas"]
ACTUATOR = ["delta_a", "delta_a_ref", "motor_torque", "motor_speed", "motor_current",
            "dc_power", "phase_current_peak", "v_dc", "chopper_power", "actuator_limits"]
CONTROLLER = ["delta_a_cmd", "theta_ref", "theta_v_hat", "solver_status"]

# channel -> {field: column of the row `step`}
JOIN = {
    "/plant/out": {f: f for f in PLANT},
    "/actuator/out": {f: f for f in ACTUATOR},
    "/controller/out": {f: f for f in CONTROLLER},
    "/plant/in": {"delta_a": "rx_bar_angle"},
    "/actuator/in": {"delta_a_cmd": "rx_actuator_command", "psi": "rx_bar_twist"},
    "/controller/in": {"theta_v_meas": "rx_measurement"},
    "/links/actuator_command": {"received": "rx_actuator_command"},
    "/links/bar_angle": {"received": "rx_bar_angle"},
    "/links/measurement": {"received": "rx_measurement"},
    "/links/bar_twist": {"received": "rx_bar_twist"},
}


def before(master):
    """channel -> {field: column of the row `step - 1`}: values from the tick's start."""
    b = {
        "/controller/in": {"time": "time", "s": "s"},
        "/links/measurement": {"sent": "theta_v_meas"},
        "/links/bar_twist": {"sent": "psi"},
    }
    sent_now = {"/links/actuator_command": "delta_a_cmd", "/links/bar_angle": "delta_a"}
    for channel, column in sent_now.items():
        if master == "jacobi":
            b[channel] = {"sent": column}
        else:
            JOIN[channel]["sent"] = column
    return b


def main() -> None:
    path, table, master = sys.argv[1], sys.argv[2], sys.argv[3]
    with open(table, newline="") as f:
        rows = list(csv.DictReader(f))
    by_step = {int(r["step"]): r for r in rows}
    earlier = before(master)
    dt_ns = round(float(by_step[1]["time"]) * 1e9)
    out = {}
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            topic = channel.topic
            r = out.setdefault(topic, {"messages": 0, "values": 0, "differ": 0, "mismatches": []})
            r["messages"] += 1
            if topic in ("/summary", "/perf"):
                continue
            v = json.loads(message.data)
            step = v["step"]
            if topic == "/events":
                pairs = [("time", step, "time")]
            else:
                pairs = [(fld, step, col) for fld, col in JOIN.get(topic, {}).items()]
                pairs += [(fld, step - 1, col) for fld, col in earlier.get(topic, {}).items()]
            if topic != "/events" and message.log_time != step * dt_ns:
                r["differ"] += 1
                r["mismatches"].append([step, "log_time", message.log_time, "step*dt", None])
            for fld, at, col in pairs:
                want = float(by_step[at][col])
                got = v.get(fld)
                r["values"] += 1
                same = (got is None and not math.isfinite(want)) or (
                    got is not None and math.isfinite(want) and float(got) == want
                )
                if not same:
                    r["differ"] += 1
                if not same and len(r["mismatches"]) < 5:
                    r["mismatches"].append([step, fld, got, col, by_step[at][col]])
    print(json.dumps(out))


if __name__ == "__main__":
    main()

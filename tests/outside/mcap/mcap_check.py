"""Reads a tiltsim run.mcap with the `mcap` package from PyPI (the reader Foxglove's Python
tools use) and prints what the recording promises, as JSON:

* `order`: messages, in file order, whose log time is below the largest before them (0 in a
  file that `mcap doctor --strict-message-order` accepts);
* `compression`: the compression of every chunk (from the summary's chunk indexes);
* `schemas`: per topic, the JSON types its schema gives each field;
* `schema_names`: per topic, its schema's name (`foxglove.Log` for the events);
* `plant_time`: /plant/out messages whose log time is not their own `t` (ns);
* `counts`: messages per topic.

    python mcap_check.py RUN.mcap
"""

import json
import sys

from mcap.reader import make_reader


def main() -> None:
    path = sys.argv[1]
    order = 0
    largest = 0
    counts = {}
    plant_time = 0
    schemas = {}
    schema_names = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        compression = sorted({c.compression for c in summary.chunk_indexes})
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            doc = json.loads(schema.data)
            schema_names[channel.topic] = schema.name
            schemas[channel.topic] = {
                name: field.get("type") for name, field in doc.get("properties", {}).items()
            }
        f.seek(0)
        reader = make_reader(f)
        for _, channel, message in reader.iter_messages(log_time_order=False):
            if message.log_time < largest:
                order += 1
            largest = max(largest, message.log_time)
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/plant/out":
                t = json.loads(message.data)["time"]
                if message.log_time != round(t * 1e9):
                    plant_time += 1
    print(
        json.dumps(
            {
                "order": order,
                "compression": compression,
                "schemas": schemas,
                "schema_names": schema_names,
                "plant_time": plant_time,
                "counts": counts,
            }
        )
    )


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Reads an interpd trace with the Python `mcap` package (no interpd code) and
checks it against expectations written by the Rust side.

    python scripts/mcap_interop.py TRACE.mcap EXPECTED.json

EXPECTED.json: {"counts": {topic: n, ...}, "setpoints": [{"seq": .., "x": .., ...}, ...]}
Every message is decoded with json.loads, and the first 300 of each topic are
validated against the channel's JSON Schema (the `jsonschema` package); the listed setpoints must match field
for field, exactly (JSON floats are shortest round-trip, so equal text means
equal bits). Exits 0 and prints one line per topic when all holds.
Needs: pip install mcap jsonschema (.ci/run does this in out/venv).
"""

import json
import sys

import jsonschema
from mcap.reader import make_reader

VALIDATE_PER_TOPIC = 300


def main(trace_path, expected_path):
    with open(expected_path, encoding="utf-8") as f:
        expected = json.load(f)
    counts = {}
    validators = {}
    setpoints = {}
    with open(trace_path, "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        if header.profile != "interpd":
            raise SystemExit(f"profile {header.profile!r}, expected 'interpd'")
        for schema, channel, message in reader.iter_messages():
            if channel.message_encoding != "json" or schema.encoding != "jsonschema":
                raise SystemExit(f"{channel.topic}: encoding {channel.message_encoding}/{schema.encoding}")
            topic = channel.topic
            if topic not in validators:
                validators[topic] = jsonschema.Draft202012Validator(json.loads(schema.data))
            msg = json.loads(message.data)
            # Schema validation is slow in Python: the first messages of each
            # topic prove the schema; every message is still decoded.
            if counts.get(topic, 0) < VALIDATE_PER_TOPIC:
                validators[topic].validate(msg)
            counts[topic] = counts.get(topic, 0) + 1
            if topic == "/interpd/setpoints":
                if message.log_time != round(msg["time"] * 1e9):
                    raise SystemExit(f"setpoint {msg['seq']}: log_time {message.log_time} != time {msg['time']}")
                setpoints[msg["seq"]] = msg
    for topic, n in expected["counts"].items():
        if counts.get(topic, 0) != n:
            raise SystemExit(f"{topic}: {counts.get(topic, 0)} messages, expected {n}")
    for want in expected["setpoints"]:
        got = setpoints.get(want["seq"])
        if got != want:
            raise SystemExit(f"setpoint {want['seq']}: got {got}, expected {want}")
    # Setpoints are gapless from 1.
    seqs = sorted(setpoints)
    if seqs != list(range(1, len(seqs) + 1)):
        raise SystemExit("setpoint sequence numbers are not 1..n")
    for topic in sorted(counts):
        print(f"{topic}: {counts[topic]} messages, schema-valid")
    print(f"checked {len(expected['setpoints'])} setpoints field for field")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    main(sys.argv[1], sys.argv[2])

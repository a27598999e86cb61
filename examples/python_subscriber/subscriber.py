#!/usr/bin/env python3
"""A minimal soft controller: reads every setpoint interpd publishes over
iceoryx2 (service `cnc/setpoints`, type `interpd::SetpointMsg`) and reports
gaps in the sequence numbers, a restart of the publisher (the sequence starts
again; the position may jump) and a dead publisher (no sample for --timeout
seconds: the service publishes every period, idle or not).

    pip install iceoryx2
    python3 subscriber.py [--service cnc/setpoints] [--until-done] [--seconds N] [--json]

Exit status 0 when no sample was missed, the publisher neither restarted nor
went silent (and with --until-done, the program reached `done`); 1
otherwise, 2 on a usage error.
The payload layout is documented in docs/daemon.md and mirrors
`daemon/src/service/publish.rs` (`SetpointMsg`, `#[repr(C)]`).
"""

import argparse
import ctypes
import json
import math
import sys
import time

import iceoryx2 as iox2

# RunState values (interp_core::RunState as u8).
STATES = ["idle", "running", "holding", "stopping", "done", "fault"]
MOVING = {1, 2, 3}
DONE = 4


class SetpointMsg(ctypes.Structure):
    """Mirror of `interpd::SetpointMsg` (104 bytes, 8-byte aligned)."""

    _fields_ = [
        ("seq", ctypes.c_uint64),
        ("tick", ctypes.c_uint64),
        ("time", ctypes.c_double),
        ("axes", ctypes.c_double * 6),
        ("feed", ctypes.c_double),
        ("u", ctypes.c_double),
        ("s", ctypes.c_double),
        ("block_id", ctypes.c_uint32),
        ("state", ctypes.c_uint32),
    ]

    @staticmethod
    def type_name() -> str:
        """The iceoryx2 type name the Rust publisher registers."""
        return "interpd::SetpointMsg"


# Must match the publisher's service settings (daemon/src/service/publish.rs).
SUBSCRIBER_BUFFER = 1024
MAX_SUBSCRIBERS = 8


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--service", default="cnc/setpoints")
    ap.add_argument("--until-done", action="store_true",
                    help="stop at the first `done` sample after motion")
    ap.add_argument("--seconds", type=float, default=None)
    ap.add_argument("--timeout", type=float, default=5.0,
                    help="the publisher is dead when no sample arrives for this long, s")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()

    assert ctypes.sizeof(SetpointMsg) == 104, ctypes.sizeof(SetpointMsg)
    iox2.set_log_level(iox2.LogLevel.Error)  # not the "no config file" warning
    node = (iox2.NodeBuilder.new()
            .signal_handling_mode(iox2.SignalHandlingMode.HandleTerminationRequests)
            .create(iox2.ServiceType.Ipc))
    service = (node.service_builder(iox2.ServiceName.new(args.service))
               .publish_subscribe(SetpointMsg)
               .subscriber_max_buffer_size(SUBSCRIBER_BUFFER)
               .max_subscribers(MAX_SUBSCRIBERS)
               .max_publishers(1)
               .history_size(0)
               .open_or_create())
    subscriber = service.subscriber_builder().buffer_size(SUBSCRIBER_BUFFER).create()
    print(f"subscribed to {args.service!r}", file=sys.stderr, flush=True)

    received = gaps = non_finite = restarts = 0
    restart_jump = 0.0
    silent = None
    first = last = None
    last_msg = None
    moved = False
    t0 = last_rx = time.monotonic()
    poll = iox2.Duration.from_millis(2)
    stop = False
    while not stop:
        while True:
            sample = subscriber.receive()
            if sample is None:
                break
            m = sample.payload().contents
            seq = m.seq
            if last is not None and seq <= last:
                # A publisher counts from 1: a lower number is a new one.
                restarts += 1
                if last_msg is not None:
                    restart_jump = max(restart_jump, math.dist(last_msg[1], m.axes[:3]))
            elif last is not None:
                gaps += seq - last - 1
            if first is None:
                first = seq
            last = seq
            received += 1
            values = [m.time, m.feed, m.u, m.s, *m.axes]
            if not all(math.isfinite(v) for v in values):
                non_finite += 1
            last_msg = (m.tick, [m.axes[0], m.axes[1], m.axes[2]], m.state)
            last_rx = time.monotonic()
            moved |= m.state in MOVING
            if args.until_done and moved and m.state == DONE:
                stop = True
                break
        now = time.monotonic()
        if args.seconds is not None and now - t0 >= args.seconds:
            break
        if now - last_rx > args.timeout:
            silent = now - last_rx
            print(f"no sample for {silent:.1f} s: the publisher is dead", file=sys.stderr)
            break
        try:
            node.wait(poll)
        except iox2.NodeWaitFailure:
            break

    summary = {
        "received": received,
        "gaps": gaps,
        "non_finite": non_finite,
        "first_seq": first,
        "last_seq": last,
        "final_state": STATES[last_msg[2]] if last_msg and last_msg[2] < len(STATES) else None,
        "final_position": last_msg[1] if last_msg else None,
        "reached_done": bool(moved and last_msg and last_msg[2] == DONE),
        "restarts": restarts,
        "restart_jump_mm": restart_jump,
        "silent_s": silent,
    }
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"{received} samples, {gaps} missing, {restarts} restarts, {non_finite} non-finite, "
              f"seq {first}..{last}, final {summary['final_state']} at {summary['final_position']}")
    if restarts:
        print(f"the publisher restarted {restarts} time(s): its sequence started again, "
              f"the position jumped {restart_jump:.6f} mm", file=sys.stderr)
    ok = received > 0 and gaps == 0 and non_finite == 0 and restarts == 0 and silent is None
    if args.until_done:
        ok = ok and summary["reached_done"]
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

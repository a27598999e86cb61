#!/usr/bin/env python3
"""An operator at the panel of a running `interpd serve`: over one connection,
the feed override stepped through 1.0 0.6 1.2 0.8 1.5 0.9 every OVERRIDE_MS,
and a feed hold every HOLD_MS resumed RESUME_MS after it, for SECONDS (issue
15: the planning thread's lead under bursts of commands). Prints how many
commands were refused (a hold while nothing moves, a resume while not
holding).

    interpd serve --port 47201 --no-socket --record run.mcap &
    scripts/serve_knob.py 47201 14 --override-ms 31 --hold-ms 47 --resume-ms 11 &
    interpd send --addr 127.0.0.1:47201 --json --quiet program.ngc   # planner_late, commands_merged
    interpd replay run.mcap
"""
import argparse
import socket
import time


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("port", type=int)
    ap.add_argument("seconds", type=float)
    ap.add_argument("--override-ms", type=float, default=113)
    ap.add_argument("--hold-ms", type=float, default=97)
    ap.add_argument("--resume-ms", type=float, default=20)
    a = ap.parse_args()
    conn = socket.create_connection(("127.0.0.1", a.port)).makefile("rw")

    def ask(line: str) -> bool:
        conn.write(line + "\n")
        conn.flush()
        return conn.readline().startswith("err")

    values = [1.0, 0.6, 1.2, 0.8, 1.5, 0.9]
    t0 = time.time()
    next_override, next_hold, k, refused = t0, t0, 0, 0
    while time.time() - t0 < a.seconds:
        now = time.time()
        if now >= next_override:
            refused += ask("override %g" % values[k % len(values)])
            k += 1
            next_override += a.override_ms / 1000
        if now >= next_hold:
            refused += ask("hold")
            time.sleep(a.resume_ms / 1000)
            refused += ask("resume")
            next_hold += a.hold_ms / 1000
        time.sleep(0.002)
    print("commands refused:", refused)


if __name__ == "__main__":
    main()

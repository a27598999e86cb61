#!/usr/bin/env python3
"""A long G6.2 curve for the planning-time benchmark (issue 15): N control
points of a rational cubic (weights 1 +/- 0.3) winding along X, knots
numbered 0, 1, 2, ... as G6.2 programs number them.

    scripts/gen_long_g62.py 10000 > long10k.ngc
    interpd simulate long10k.ngc --json
"""
import math
import sys


def main() -> None:
    n = int(sys.argv[1])
    if n < 4:
        sys.exit("N must be at least 4 (a cubic)")
    out = sys.stdout
    out.write("G21 G90 G94 G17\nG0 X0 Y5 Z0.1\nF6000\n")
    for i in range(n):
        x, y, z = 0.5 * i, 5 * math.cos(0.3 * i), 0.1 * math.cos(0.7 * i)
        w = 1.0 + 0.3 * math.sin(i)
        k = 0 if i < 4 else i - 3
        head = "G6.2" if i == 0 else "   "
        tail = " P4 Q1" if i == 0 else ""
        out.write(f"{head} X{x:.6f} Y{y:.6f} Z{z:.6f} R{w:.6f} K{k}{tail}\n")
    for _ in range(4):
        out.write(f"G6.2 K{n - 3}\n")
    out.write("M2\n")


if __name__ == "__main__":
    main()

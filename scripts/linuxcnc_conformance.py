#!/usr/bin/env python3
"""Compare interpd's G-code reading with LinuxCNC's standalone interpreter.

For every program given (default: the .ngc files of /usr/share/linuxcnc/ncfiles
and gcode/tests/programs), run

  * LinuxCNC: `rs274 -g FILE` (Debian package linuxcnc-uspace), which prints the
    canonical machining calls, and
  * interpd:  `gcode/examples/canon.rs` (JSON lines, one per move),

and compare, move by move, the end points, arc centres and rotations, and
feeds (mm/min). A program is *covered* when both interpreters read it to the
end without error; the others are listed with the reason and not compared.

Tolerance: 1e-4 mm for programs in millimetres. rs274 prints 4 decimals in
the program's units, so for G20 programs the comparison is within the printed
precision (0.5e-4 inch, ~1.3e-3 mm).

NURBS: rs274 prints only `NURBS_FEED(n, ...)` (the control point count), so a
NURBS move is compared by its control point count and by the position after it.

Usage:
  scripts/linuxcnc_conformance.py [--canon PATH] [--json OUT] [FILES...]

Exit status 0 when every covered program matches, 1 otherwise.
"""

import argparse
import glob
import json
import math
import os
import re
import subprocess
import sys

MM_PER_INCH = 25.4
TOL_MM = 1e-4
TOL_INCH_PRINTED = 0.5e-4 * MM_PER_INCH * 1.01
RS274_TIMEOUT_S = 20

CALL = re.compile(r"^\s*\d+\s+N\S*\s+([A-Z_0-9]+)\((.*)\)\s*$")


def numbers(args):
    out = []
    for a in args.split(","):
        a = a.strip()
        try:
            out.append(float(a))
        except ValueError:
            out.append(a)
    return out


def run_rs274(path):
    """LinuxCNC's moves, or (None, reason)."""
    try:
        p = subprocess.run(
            ["rs274", "-g", path],
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            timeout=RS274_TIMEOUT_S,
        )
    except subprocess.TimeoutExpired:
        return None, "rs274 timed out", False
    moves = []
    scale = 1.0
    inch = False
    plane = 17
    feed = 0.0
    inverse = False
    pos = [0.0, 0.0, 0.0]
    ok = True
    reason = ""
    lines = p.stdout.splitlines()
    for i, line in enumerate(lines):
        m = CALL.match(line)
        if not m:
            # rs274 prints the error text and the offending line, then resets.
            if line.strip() and line.strip() != "executing" and not line.startswith(" "):
                ok = False
                reason = reason or "rs274: " + line.strip()
            continue
        name, args = m.group(1), numbers(m.group(2))
        if name == "USE_LENGTH_UNITS":
            inch = "INCH" in m.group(2)
            scale = MM_PER_INCH if inch else 1.0
        elif name == "SELECT_PLANE":
            plane = {"CANON_PLANE_XY": 17, "CANON_PLANE_XZ": 18, "CANON_PLANE_YZ": 19}.get(m.group(2).strip(), 0)
        elif name == "SET_FEED_RATE":
            feed = args[0]
        elif name == "SET_FEED_MODE":
            pass
        elif name == "COMMENT" and "inverse time" in m.group(2):
            inverse = True
        elif name == "COMMENT" and "units per minute" in m.group(2):
            inverse = False
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            pos = [args[0] * scale, args[1] * scale, args[2] * scale]
            mv = {"kind": "rapid" if name == "STRAIGHT_TRAVERSE" else "feed", "end": pos, "inch": inch}
            if name == "STRAIGHT_FEED":
                mv["feed"] = feed * scale
            moves.append(mv)
        elif name == "ARC_FEED":
            e1, e2, c1, c2, rot, ae = [a * scale if k != 4 else a for k, a in enumerate(args[:6])]
            idx = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}[plane]
            end = [0.0, 0.0, 0.0]
            end[idx[0]], end[idx[1]], end[idx[2]] = e1, e2, ae
            centre = list(pos)
            centre[idx[0]], centre[idx[1]] = c1, c2
            moves.append({"kind": "arc", "end": end, "centre": centre, "plane": plane, "rotation": int(rot),
                          "feed": feed * scale, "inch": inch})
            pos = end
        elif name in ("NURBS_FEED", "NURBS_G5_FEED", "NURBS_G6_FEED"):
            n = int(re.match(r"\s*(\d+)", m.group(2)).group(1))
            moves.append({"kind": "nurbs", "control_points": n, "inch": inch})
        elif name in ("STRAIGHT_PROBE", "RIGID_TAP"):
            ok = False
            reason = reason or f"rs274: {name} (not in the subset)"
    if p.returncode != 0 and ok:
        ok = False
        # rs274 writes "executing", then the error and the offending line, to stderr.
        msg = [l.strip() for l in p.stderr.splitlines() if l.strip() and l.strip() != "executing"]
        reason = "rs274: " + " / ".join(msg[:2]) if msg else f"rs274 exit status {p.returncode}"
    return moves, reason, ok


def run_ours(canon, path):
    p = subprocess.run([canon, path], capture_output=True, text=True)
    moves = []
    for line in p.stdout.splitlines():
        rec = json.loads(line)
        if "error" in rec:
            return None, "interpd: " + rec["error"]
        moves.append(rec)
    if p.returncode != 0:
        return None, f"interpd canon exit status {p.returncode}: {p.stderr.strip()}"
    return moves, ""


def close(a, b, tol):
    return all(abs(x - y) <= tol for x, y in zip(a, b))


def compare(theirs, ours):
    """(moves matched, first mismatch or None). NURBS positions come from the next move."""
    # Our NURBS blocks give the end point; LinuxCNC's next move starts there, so
    # compare NURBS by control point count only.
    if len(theirs) != len(ours):
        return 0, f"{len(theirs)} moves in LinuxCNC, {len(ours)} in interpd"
    matched = 0
    for i, (t, o) in enumerate(zip(theirs, ours)):
        tol = TOL_INCH_PRINTED if t.get("inch") else TOL_MM
        where = f"move {i + 1} (our line {o.get('line')})"
        if t["kind"] != o["kind"]:
            return matched, f"{where}: kind {t['kind']} vs {o['kind']}"
        if t["kind"] == "nurbs":
            if t["control_points"] != o["control_points"]:
                return matched, f"{where}: {t['control_points']} vs {o['control_points']} control points"
            matched += 1
            continue
        if not close(t["end"], o["end"], tol):
            return matched, f"{where}: end {t['end']} vs {o['end']}"
        if t["kind"] == "arc":
            if not close(t["centre"], o["centre"], tol):
                return matched, f"{where}: centre {t['centre']} vs {o['centre']}"
            if t["rotation"] != o["rotation"] or t["plane"] != o["plane"]:
                return matched, f"{where}: rotation/plane {t['rotation']}/{t['plane']} vs {o['rotation']}/{o['plane']}"
        if t["kind"] in ("feed", "arc") and "feed" in o:
            ftol = max(tol, 1e-9 * abs(t["feed"]))
            if abs(t["feed"] - o["feed"]) > ftol:
                return matched, f"{where}: feed {t['feed']} vs {o['feed']}"
        matched += 1
    return matched, None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    ap.add_argument("--canon", default=os.path.join(root, "target", "release", "examples", "canon"),
                    help="interpd's canon dump (cargo build --release -p gcode --example canon)")
    ap.add_argument("--json", help="write the per-file results here")
    ap.add_argument("files", nargs="*")
    a = ap.parse_args()
    files = a.files or sorted(glob.glob("/usr/share/linuxcnc/ncfiles/*.ngc")) + sorted(
        glob.glob(os.path.join(root, "gcode", "tests", "programs", "*.ngc"))) + sorted(
        glob.glob("/work/shared/corpus/nurbs-linuxcnc/*/*.ngc"))
    if not os.path.exists(a.canon):
        sys.exit(f"{a.canon} missing: cargo build --release -p gcode --example canon")
    results = []
    covered = matched_files = moves_total = moves_matched = 0
    prefix_files = prefix_moves = prefix_matched = 0
    for f in files:
        theirs, reason_t, ok_t = run_rs274(f)
        ours, reason_o = run_ours(a.canon, f)
        name = os.path.relpath(f)
        if ours is not None and not ok_t and theirs:
            # LinuxCNC stopped part way (e.g. Debian's 2.9 knows no G6.2): compare
            # what it did before the error; the program is not counted as covered.
            n, mismatch = compare(theirs, ours[: len(theirs)])
            prefix_files += 1
            prefix_moves += len(theirs)
            prefix_matched += n if mismatch else len(theirs)
            state = f"mismatch: {mismatch}" if mismatch else "match"
            print(f"part  {name}: {reason_t}; the {len(theirs)} moves before it {state}")
            results.append({"file": name, "covered": False, "reason": reason_t, "prefix_moves": len(theirs),
                            "prefix_mismatch": mismatch})
            continue
        if ours is None or not ok_t:
            why = "; ".join(r for r in (reason_t if not ok_t else "", reason_o) if r)
            print(f"skip  {name}: {why}")
            results.append({"file": name, "covered": False, "reason": why})
            continue
        covered += 1
        n, mismatch = compare(theirs, ours)
        moves_total += len(theirs)
        moves_matched += n if mismatch else len(theirs)
        if mismatch:
            print(f"FAIL  {name}: {mismatch}")
        else:
            matched_files += 1
            print(f"ok    {name}: {len(theirs)} moves")
        results.append({"file": name, "covered": True, "moves": len(theirs), "mismatch": mismatch})
    print(f"\n{covered} of {len(files)} programs covered; {matched_files} match; "
          f"{moves_matched} of {moves_total} moves compared equal")
    print(f"{prefix_files} programs LinuxCNC stopped part way: {prefix_matched} of {prefix_moves} "
          f"moves before the stop compared equal")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(results, fh, indent=1)
    sys.exit(0 if matched_files == covered else 1)


if __name__ == "__main__":
    main()

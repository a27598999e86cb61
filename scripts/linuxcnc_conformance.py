#!/usr/bin/env python3
"""Compare interpd's G-code reading with LinuxCNC's standalone interpreter.

For every program given (default: the .ngc files of /usr/share/linuxcnc/ncfiles,
gcode/tests/programs and /work/shared/corpus/nurbs-linuxcnc), run

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

NURBS paths (second part, when LinuxCNC's `linuxcnc` launcher is installed):
rs274 never draws a NURBS; LinuxCNC 2.9 turns each G5.2 (and G5/G5.1) curve
into arcs in its task (emccanon's NURBS_FEED: 4 spans per control point,
uniform in u, each span a biarc through the curve's points and tangents at
both ends). So every program with a NURBS is also run through a headless
LinuxCNC (milltask + motion, simulated machine, written to a temporary
directory) with EMC_DEBUG_TASK_ISSUE, which prints each arc and line the task
sends to motion (end, centre, normal, turns; 6 decimals). For each of our
curves the script then reports
  * what was compared: "as written" (LinuxCNC ran the file's curve), or
    "as G5.2 in XY" when LinuxCNC 2.9 refuses the file's curve (G6.2 is
    unknown to it, its G5.2 is XY only) but can express it: the curve as we
    read it, knot vector LinuxCNC's clamped uniform one up to scale, written
    as a G5.2 L<order> program with the plane's two axes as X Y and run
    instead; or why nothing was compared;
  * junction deviation: LinuxCNC's biarc joints are points of its own exact
    curve at u_i = i/(4 n) of the knot range; the distance of each to our
    curve at the same u_i (tolerance 2e-6 mm, the printed precision) shows
    both read the same curve;
  * approximation deviation: the Hausdorff distance between LinuxCNC's arcs
    and our exact curve (both directions, span by span, our curve sampled
    until its chords are within 1e-7 mm), which is LinuxCNC's approximation
    error: interpd interpolates the exact curve.
Our curve is built from the control points, weights and knots our canon dump
prints; the joints are compared with geomdl's evaluation (the project's NURBS
reference), the dense sampling uses a vectorised de Boor checked against
geomdl at every joint (1e-9 mm). Needs numpy and geomdl==5.4.0 for the
running Python; the LinuxCNC driver runs under /usr/bin/python3 (Debian's
python3-linuxcnc).

A span LinuxCNC draws nothing for (its biarc has no solution: straight or
standing-still spans) is listed with the gap it leaves (there and on the
next span, whose first arc motion turns into a spiral); a curve LinuxCNC
cannot express as G5.2 (order 2, knots not uniform) or does not finish
computing within --program-timeout is listed as not compared, with why.

Usage:
  scripts/linuxcnc_conformance.py [--canon PATH] [--json OUT] [--no-task]
      [--program-timeout S] [--workdir DIR [--reuse]] [FILES...]
  scripts/linuxcnc_conformance.py --self-test   # parser and measurement on made-up moves

Exit status 0 when every covered program matches and every compared curve's
junctions lie on our curve, 1 otherwise.
"""

import argparse
import glob
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile

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

# ---------------------------------------------------------------------------
# NURBS paths: LinuxCNC's task (biarcs) against our exact curve.

LCNC_PYTHON = "/usr/bin/python3"  # Debian's python3-linuxcnc lives here
# LinuxCNC 2.9 computes each G5.2 curve in its interpreter before a move is
# issued, at a cost that grows as n^2 per point (n control points): a
# program it has not finished in this time is reported and left.
PROGRAM_TIMEOUT_S = 120
JUNCTION_TOL_MM = 2e-6  # the task prints 6 decimals
CHORD_SAG_MM = 1e-7  # our curve's sampling: chord sag bound per span
MARK = "@@conformance"

# A machine far faster than any program asks for, so the moves run in a few
# servo periods each (the task issues them as motion's queue drains).
_AXIS = "MAX_VELOCITY = 100000\nMAX_ACCELERATION = 1e7\nMIN_LIMIT = -1e6\nMAX_LIMIT = 1e6\n"
_JOINT = ("TYPE = LINEAR\nHOME = 0\n" + _AXIS + "FERROR = 1e6\nMIN_FERROR = 1e6\nHOME_OFFSET = 0\n"
          "HOME_SEARCH_VEL = 0\nHOME_LATCH_VEL = 0\nHOME_SEQUENCE = 0\n")
TASK_INI = """[EMC]
VERSION = 1.1
MACHINE = interpd-conformance
# EMC_DEBUG_TASK_ISSUE: print every command the task issues, with its fields
DEBUG = 0x10
[DISPLAY]
DISPLAY = {driver}
CYCLE_TIME = 0.100
POSITION_OFFSET = RELATIVE
POSITION_FEEDBACK = COMMANDED
MAX_FEED_OVERRIDE = 100.0
[TASK]
TASK = milltask
CYCLE_TIME = 0.001
[RS274NGC]
PARAMETER_FILE = sim.var
[EMCMOT]
EMCMOT = motmod
COMM_TIMEOUT = 1.0
BASE_PERIOD = 0
SERVO_PERIOD = 1000000
[EMCIO]
EMCIO = io
CYCLE_TIME = 0.100
TOOL_TABLE = sim.tbl
[HAL]
HALFILE = core.hal
[TRAJ]
COORDINATES = X Y Z
LINEAR_UNITS = mm
ANGULAR_UNITS = degree
DEFAULT_LINEAR_VELOCITY = 100
MAX_LINEAR_VELOCITY = 100000
DEFAULT_LINEAR_ACCELERATION = 1e7
MAX_LINEAR_ACCELERATION = 1e7
NO_FORCE_HOMING = 1
[KINS]
KINEMATICS = trivkins coordinates=XYZ
JOINTS = 3
""" + "".join(f"[AXIS_{a}]\n{_AXIS}" for a in "XYZ") + "".join(f"[JOINT_{j}]\n{_JOINT}" for j in range(3))
TASK_HAL = """loadrt [KINS]KINEMATICS
loadrt [EMCMOT]EMCMOT base_period_nsec=[EMCMOT]BASE_PERIOD servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS
addf motion-command-handler servo-thread
addf motion-controller servo-thread
net Xpos joint.0.motor-pos-cmd => joint.0.motor-pos-fb
net Ypos joint.1.motor-pos-cmd => joint.1.motor-pos-fb
net Zpos joint.2.motor-pos-cmd => joint.2.motor-pos-fb
net estop-loop iocontrol.0.user-enable-out iocontrol.0.emc-enable-in
net tool-prep-loop iocontrol.0.tool-prepare iocontrol.0.tool-prepared
net tool-change-loop iocontrol.0.tool-change iocontrol.0.tool-changed
"""
TASK_DRIVER = """#!{python}
import sys
sys.dont_write_bytecode = True
sys.path.insert(0, {here!r})
import linuxcnc_conformance
linuxcnc_conformance.driver_main()
"""
# Before each program: the modes and the position rs274 and interpd start from.
RESET_MDI = "G17 G21 G40 G49 G54 G64 G90 G91.1 G94 G0 X0 Y0 Z0"


def driver_main():
    """LinuxCNC's DISPLAY program: runs each of $CONFORMANCE_PROGRAMS and marks
    where each begins and ends in the task's output (the same stream)."""
    import time
    import linuxcnc

    def mark(*words):
        print(MARK, *words, flush=True)

    s, c, e = linuxcnc.stat(), linuxcnc.command(), linuxcnc.error_channel()
    t0 = time.time()
    while True:
        try:
            s.poll()
            break
        except linuxcnc.error:
            if time.time() - t0 > 30:
                mark("FATAL", "task never came up")
                sys.exit(1)
            time.sleep(0.2)

    def errors():
        out = []
        while True:
            m = e.poll()
            if not m:
                return out
            if m[0] in (linuxcnc.NML_ERROR, linuxcnc.OPERATOR_ERROR):
                out.append(" ".join(str(m[1]).split()))

    def wait_idle(limit):
        t = time.time()
        while time.time() - t < limit:
            s.poll()
            if s.task_state != linuxcnc.STATE_ON:
                return "the machine left the ON state"
            if s.interp_state == linuxcnc.INTERP_IDLE and s.queue == 0 and s.exec_state == linuxcnc.EXEC_DONE:
                return ""
            time.sleep(0.01)
        return f"not finished after {limit:.0f} s"

    def machine_on():
        c.state(linuxcnc.STATE_ESTOP_RESET); c.wait_complete()
        c.state(linuxcnc.STATE_ON); c.wait_complete()
        c.mode(linuxcnc.MODE_MANUAL); c.wait_complete()
        c.home(-1); c.wait_complete()
        for _ in range(100):
            s.poll()
            if all(s.homed[:3]):
                break
            time.sleep(0.05)

    machine_on()
    c.feedrate(100.0)
    for prog in os.environ["CONFORMANCE_PROGRAMS"].split("\n"):
        s.poll()
        if s.task_state != linuxcnc.STATE_ON:
            machine_on()
        c.reset_interpreter(); c.wait_complete()
        c.mode(linuxcnc.MODE_MDI); c.wait_complete()
        c.mdi(RESET_MDI); c.wait_complete()
        wait_idle(PROGRAM_TIMEOUT_S)
        errors()
        c.mode(linuxcnc.MODE_AUTO); c.wait_complete()
        mark("BEGIN", prog)
        c.program_open(prog); c.wait_complete()
        c.auto(linuxcnc.AUTO_RUN, 0)
        time.sleep(0.2)
        trouble = wait_idle(float(os.environ.get("CONFORMANCE_PROGRAM_TIMEOUT", PROGRAM_TIMEOUT_S)))
        time.sleep(0.05)
        refused = errors()
        for msg in refused:
            mark("ERROR", msg)
        if trouble:
            # The task may be stuck inside the curve: the launcher kills it when
            # this driver exits.
            mark("ERROR", trouble)
        mark("END", prog)
        if refused or trouble:
            # LinuxCNC 2.9 keeps a refused G5.2 curve's points (a static list
            # in convert_nurbs) and the next program's first G5.2 line then
            # fails: the rest runs in a new LinuxCNC.
            break
    c.state(linuxcnc.STATE_OFF); c.wait_complete()
    mark("EXIT")


def parse_task_output(text):
    """{program: {"moves": [...], "errors": [...]}} from the task's output.
    Moves in machine mm (this machine has no offsets): {"kind": "line"|"arc",
    "end", "rapid"} and for arcs "centre", "normal", "ccw", "turns"."""
    runs = {}
    cur = None
    for line in text.splitlines():
        if line.startswith(MARK):
            parts = line[len(MARK):].strip().split(" ", 1)
            if parts[0] == "BEGIN":
                cur = runs.setdefault(parts[1], {"moves": [], "errors": [], "ended": False})
            elif parts[0] == "END":
                if cur is not None:
                    cur["ended"] = True
                cur = None
            elif parts[0] == "ERROR" and cur is not None:
                cur["errors"].append(parts[1] if len(parts) > 1 else "?")
            continue
        if cur is None or not line.startswith("Issuing EMC_TRAJ_"):
            continue
        m = re.match(r"Issuing (EMC_TRAJ_LINEAR_MOVE|EMC_TRAJ_CIRCULAR_MOVE) --\s*\((.*)\)\s*$", line)
        if not m:
            continue
        f = [x.strip() for x in m.group(2).split(",")]
        # EMC_TRAJ_CMD_MSG (type, size, serial), EmcPose end (x y z a b c u v w), then
        # linear: type vel ini_maxvel acc feed_mode indexer; circular: centre, normal,
        # turn, type, ...
        end = [float(v) for v in f[3:6]]
        if m.group(1) == "EMC_TRAJ_LINEAR_MOVE":
            cur["moves"].append({"kind": "line", "end": end, "rapid": int(f[12]) == 1})
        else:
            turn = int(f[18])
            cur["moves"].append({"kind": "arc", "end": end, "centre": [float(v) for v in f[12:15]],
                                 "normal": [float(v) for v in f[15:18]], "ccw": turn >= 0,
                                 "turns": turn if turn >= 0 else -turn - 1, "rapid": False})
    return runs


def run_task(programs, workdir, program_timeout=PROGRAM_TIMEOUT_S, reuse=False):
    """Runs the programs through a headless LinuxCNC, a new one after each
    program it refuses; (runs, None) or (None, reason). With reuse, reads
    the output an earlier run left in workdir instead."""
    if reuse:
        runs = {}
        for log in sorted(glob.glob(os.path.join(workdir, "session-*", "task.out"))):
            runs.update(parse_task_output(open(log, errors="replace").read()))
        missing = [p for p in programs if p not in runs]
        return (None, f"{len(missing)} programs not in {workdir}, e.g. {missing[0]}") if missing else (runs, None)
    runs = {}
    todo = list(programs)
    session = 0
    while todo:
        session += 1
        got, err = _run_task_session(todo, os.path.join(workdir, f"session-{session}"), program_timeout)
        if err:
            return None, err
        runs.update(got)
        done = [p for p in todo if p in got and got[p]["ended"]]
        if not done:
            return None, f"LinuxCNC ran none of its programs ({workdir}/session-{session})"
        todo = [p for p in todo if p not in done]
    return runs, None


def _run_task_session(programs, workdir, program_timeout):
    """One headless LinuxCNC on the programs; (runs, None) or (None, reason)."""
    os.makedirs(workdir, exist_ok=True)
    here = os.path.dirname(os.path.abspath(__file__))
    driver = os.path.join(workdir, "driver")
    with open(driver, "w") as fh:
        fh.write(TASK_DRIVER.format(python=LCNC_PYTHON, here=here))
    os.chmod(driver, 0o755)
    with open(os.path.join(workdir, "sim.ini"), "w") as fh:
        fh.write(TASK_INI.format(driver=driver))
    with open(os.path.join(workdir, "core.hal"), "w") as fh:
        fh.write(TASK_HAL)
    with open(os.path.join(workdir, "sim.tbl"), "w") as fh:
        fh.write("T1 P1 D1.0 Z0 ;\n")
    open(os.path.join(workdir, "sim.var"), "w").close()
    env = dict(os.environ, CONFORMANCE_PROGRAMS="\n".join(programs),
               CONFORMANCE_PROGRAM_TIMEOUT=str(program_timeout))
    if os.getuid() == 0:
        # uspace's rtapi_app refuses to run as root without a fallback user,
        # which must be able to create the rtapi socket.
        rt = os.path.join(workdir, "rtapi")
        os.makedirs(rt, exist_ok=True)
        os.chown(rt, 65534, -1)
        env.update(RTAPI_UID="65534", RTAPI_FIFO_PATH=os.path.join(rt, "rtapi_fifo"))
    log = os.path.join(workdir, "task.out")
    limit = 60 + len(programs) * (program_timeout + 30)
    with open(log, "w") as out:
        # -r: keep the output on our descriptors (without a terminal the
        # launcher would send it to a temporary file and delete it).
        p = subprocess.Popen(["linuxcnc", "-r", "sim.ini"], cwd=workdir, env=env, stdin=subprocess.DEVNULL,
                             stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            p.wait(timeout=limit)
        except subprocess.TimeoutExpired:
            # SIGTERM to the launcher's group: its trap shuts LinuxCNC down.
            os.killpg(p.pid, signal.SIGTERM)
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
            return None, f"linuxcnc did not finish in {limit} s (log {log})"
    text = open(log, errors="replace").read()
    runs = parse_task_output(text)
    if f"{MARK} EXIT" not in text:
        return None, f"linuxcnc exit status {p.returncode}, the driver did not finish (log {log})"
    return runs, None


class Curve:
    """Our curve as the canon dump gives it, evaluated with geomdl, in the
    plane's coordinates (first, second) = X Y (G17), Z X (G18), Y Z (G19)."""

    AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}

    def __init__(self, rec):
        from geomdl import NURBS

        self.rec = rec
        self.axes = self.AXES[rec["plane"]]
        i, j, k = self.axes
        self.order = rec["degree"] + 1
        self.points = rec["points"]
        self.curve = NURBS.Curve()
        self.curve.degree = rec["degree"]
        self.curve.ctrlpts = [[p[i], p[j], p[k]] for p in rec["points"]]
        self.curve.weights = list(rec["weights"])
        self.curve.knotvector = list(rec["knots"])  # geomdl maps the range onto [0, 1]

    def g5_2_uniform(self):
        """True when the knots are LinuxCNC G5.2's clamped uniform vector up to scale."""
        n, o, k = len(self.points), self.order, self.rec["knots"]
        g = [0.0] * o + [float(i) for i in range(1, n - o + 1)] + [float(n - o + 1)] * o
        if len(k) != len(g) or g[-1] == 0:
            return False
        a = (k[-1] - k[0]) / g[-1]
        return all(abs(k[0] + a * gi - ki) <= 1e-9 * max(1.0, abs(ki)) for gi, ki in zip(g, k))

    def reference(self, params):
        """geomdl's points at params (0..1 over the knot range), plane coordinates."""
        import numpy as np

        return np.array(self.curve.evaluate_list([float(u) for u in params]))[:, :2]

    def eval(self, params):
        """Points at params (0..1 over the knot range), plane coordinates: de
        Boor's triangle on homogeneous points, vectorised over params (geomdl
        takes ~50 us a point; the sampling needs millions). Checked against
        geomdl where the joints are compared."""
        import numpy as np

        u = np.asarray(params, dtype=float)
        k = np.asarray(self.curve.knotvector)  # geomdl's, normalised to 0..1
        p = self.curve.degree
        cw = np.asarray(self.curve.ctrlptsw)[:, [0, 1, 3]]  # x w, y w, w
        n = len(cw)
        span = np.clip(np.searchsorted(k, u, side="right") - 1, p, n - 1)
        d = np.stack([cw[span - p + r] for r in range(p + 1)], axis=1)  # (m, p+1, 3)
        for r in range(1, p + 1):
            for q in range(p, r - 1, -1):
                i = span - p + q
                den = k[i + p - r + 1] - k[i]
                a = np.where(den > 0, (u - k[i]) / np.where(den > 0, den, 1), 0.0)[:, None]
                d[:, q] = (1 - a) * d[:, q - 1] + a * d[:, q]
        h = d[:, p]
        return h[:, :2] / h[:, 2:3]

    def spans(self, div):
        """Dense samples of each of the div equal parameter spans: a list of
        (div) arrays, chords within CHORD_SAG_MM of the curve."""
        import numpy as np

        out = []
        for i in range(div):
            n = 32
            while True:
                u = np.linspace(i / div, (i + 1) / div, n + 1)
                pts = self.eval(u)
                sag = np.max(np.linalg.norm(pts[:-2] + pts[2:] - 2 * pts[1:-1], axis=1)) / 4 if n > 1 else 0.0
                if sag <= CHORD_SAG_MM or n >= 1 << 15:
                    out.append(pts)
                    break
                n *= 4 if sag > 16 * CHORD_SAG_MM else 2
        return out


def _piece_distance(p, piece):
    """Distances of points p (m x 2) to one LinuxCNC move in the XY plane."""
    import numpy as np

    s, e = piece["start"], piece["end2"]
    if piece.get("spiral"):
        return _segment_distance(p, _piece_samples(piece, 2048))
    if piece["kind"] == "line" or piece.get("r", 0) == 0:
        d = e - s
        L2 = float(d @ d)
        t = np.clip(((p - s) @ d) / L2, 0, 1) if L2 > 0 else np.zeros(len(p))
        return np.linalg.norm(p - (s + t[:, None] * d), axis=1)
    c, r = piece["c"], piece["r"]
    a0, sweep = piece["a0"], piece["sweep"]
    v = p - c
    ang = np.arctan2(v[:, 1], v[:, 0])
    rel = (ang - a0) * (1 if piece["ccw"] else -1)
    rel = np.mod(rel, 2 * np.pi)
    inside = rel <= sweep
    radial = np.abs(np.linalg.norm(v, axis=1) - r)
    ends = np.minimum(np.linalg.norm(p - s, axis=1), np.linalg.norm(p - e, axis=1))
    return np.where(inside, radial, ends)


def _piece_samples(piece, m=24):
    import numpy as np

    if piece["kind"] == "line" or piece.get("r", 0) == 0:
        t = np.linspace(0, 1, m + 1)[:, None]
        return piece["start"] + t * (piece["end2"] - piece["start"])
    f = np.linspace(0, 1, m + 1)
    t = f * piece["sweep"] * (1 if piece["ccw"] else -1) + piece["a0"]
    r = piece["r"] + f * piece.get("spiral", 0.0)
    return piece["c"] + r[:, None] * np.stack([np.cos(t), np.sin(t)], axis=1)


def _segment_distance(p, poly):
    """Distances of points p (m x 2) to the polyline poly (k x 2)."""
    import numpy as np

    a, b = poly[:-1], poly[1:]
    d = b - a
    L2 = np.maximum((d * d).sum(axis=1), 1e-300)
    best = np.full(len(p), np.inf)
    for lo in range(0, len(a), 4096):
        aa, dd, ll = a[lo:lo + 4096], d[lo:lo + 4096], L2[lo:lo + 4096]
        w = p[:, None, :] - aa[None, :, :]
        t = np.clip((w * dd[None]).sum(axis=2) / ll[None], 0, 1)
        q = aa[None] + t[..., None] * dd[None]
        best = np.minimum(best, np.linalg.norm(p[:, None, :] - q, axis=2).min(axis=1))
    return best


def measure_curve(curve, span_moves, start):
    """Our curve against LinuxCNC's moves for it, span by span (span_moves[i]:
    the moves of LinuxCNC's biarc i, none where it drew nothing), in XY
    (machine mm; a translated curve's plane axes are X Y). Returns numbers."""
    import numpy as np

    div = len(span_moves)
    pieces = []  # per span, with the real start of each move (after a gap too)
    pos = np.array(start[:2], dtype=float)
    for moves in span_moves:
        ps = []
        for mv in moves:
            e = np.array(mv["end"][:2], dtype=float)
            pc = {"kind": mv["kind"], "start": pos, "end2": e}
            if mv["kind"] == "arc":
                c = np.array(mv["centre"][:2], dtype=float)
                ccw = mv["ccw"] == (mv["normal"][2] >= 0)  # as seen from +Z
                a0 = math.atan2(*(pos - c)[::-1])
                a1 = math.atan2(*(e - c)[::-1])
                sweep = ((a1 - a0) if ccw else (a0 - a1)) % (2 * math.pi) + 2 * math.pi * mv["turns"]
                r = float(np.linalg.norm(pos - c))
                pc.update(c=c, r=r, ccw=ccw, a0=a0, sweep=sweep)
                if abs(float(np.linalg.norm(e - c)) - r) > 1e-5:
                    # An arc whose end is off its start's circle: motion (posemath's
                    # pmCircleInit) runs it as a spiral, the radius changing linearly
                    # with the angle.
                    pc["spiral"] = float(np.linalg.norm(e - c)) - r
            ps.append(pc)
            pos = e
        pieces.append(ps)
    moves = [m for ms in span_moves for m in ms]
    drawn = [i for i in range(div) if span_moves[i]]
    result = {"linuxcnc_moves": len(moves), "arcs": sum(m["kind"] == "arc" for m in moves),
              "lines": sum(m["kind"] == "line" for m in moves), "spans": div, "spans_drawn": len(drawn)}
    if drawn:
        # The last move of LinuxCNC's biarc i ends on its exact curve at u_i.
        joints = np.array([span_moves[i][-1]["end"][:2] for i in drawn])
        ours = curve.reference([(i + 1) / div for i in drawn])
        result["junction_max_mm"] = float(np.max(np.linalg.norm(joints - ours, axis=1)))
        result["sampler_vs_geomdl_mm"] = float(np.max(np.linalg.norm(curve.eval([(i + 1) / div for i in drawn]) - ours,
                                                                     axis=1)))
    spans = curve.spans(div)
    result["curve_samples"] = int(sum(len(s) for s in spans))
    # A span is clean when LinuxCNC drew it from where it should start (the
    # previous joint): there the distance is its approximation error. Where it
    # drew nothing, its path skips to the next span, whose first arc then
    # starts off its circle (motion makes a spiral of it): that is a gap,
    # measured apart.
    clean = [bool(span_moves[i]) and (i == 0 or bool(span_moves[i - 1])) for i in range(div)]
    everything = [pc for ps in pieces for pc in ps]
    dev = gap = 0.0
    where = None
    for i in range(div):
        if clean[i]:
            near = [pc for ps in pieces[max(0, i - 1): i + 2] for pc in ps]
        else:
            # The path that stands in for the span: the drawn spans around it
            # (not the whole path: a closed curve's end lies at its start).
            lo, hi = i, i + 1
            while lo > 0 and not span_moves[lo - 1]:
                lo -= 1
            while hi < div and not span_moves[hi]:
                hi += 1
            near = [pc for ps in pieces[max(0, lo - 1): hi + 1] for pc in ps] or everything
        d = np.min([_piece_distance(spans[i], pc) for pc in near], axis=0)
        if not clean[i]:
            gap = max(gap, float(np.max(d)))
            continue
        k = int(np.argmax(d))
        if d[k] > dev:
            dev, where = float(d[k]), spans[i][k]
        poly = np.concatenate(spans[max(0, i - 1): i + 2])
        for pc in pieces[i]:
            dev = max(dev, float(np.max(_segment_distance(_piece_samples(pc), poly))))
    result["deviation_max_mm"] = dev
    if where is not None:
        result["deviation_max_at"] = [round(float(where[0]), 4), round(float(where[1]), 4)]
    if not all(clean):
        result["spans_not_drawn"] = [i + 1 for i in range(div) if not span_moves[i]]
        result["gap_max_mm"] = gap
    return result


def g5_2_program(curves):
    """A G5.2 program (XY, mm) of our curves: each starts with a G0 to its
    first point, whose weight is given by the first line's P. The feed is one
    for all (it does not change LinuxCNC's arcs), so files that differ only in
    Q and F give one program."""
    out = ["(interpd conformance: curves as read by interpd, as LinuxCNC G5.2 in XY)",
           "G17 G21 G40 G90 G94"]
    for cv in curves:
        i, j, k = cv.axes
        p = cv.points
        w = cv.rec["weights"]
        out.append(f"G0 X{p[0][i]:.9f} Y{p[0][j]:.9f} Z{p[0][k]:.9f}")
        out.append("F1000")
        out.append(f"G5.2 P{w[0]!r} L{cv.order}")
        for q, wq in zip(p[1:], w[1:]):
            out.append(f"X{q[i]:.9f} Y{q[j]:.9f} P{wq!r}")
        out.append("G5.3")
    out.append("M2")
    return "\n".join(out) + "\n"


def compact(nums):
    """[1, 2, 3, 7] -> "1-3, 7"."""
    out, i = [], 0
    while i < len(nums):
        k = i
        while k + 1 < len(nums) and nums[k + 1] == nums[k] + 1:
            k += 1
        out.append(f"{nums[i]}-{nums[k]}" if k > i else f"{nums[i]}")
        i = k + 1
    return ", ".join(out)


def translatable(curve):
    """None when LinuxCNC 2.9's G5.2 can express our curve, else why not."""
    if curve.order < 3:
        return f"order {curve.order}: LinuxCNC's G5.2 takes only L >= 3"
    if not curve.g5_2_uniform():
        return "knots are not LinuxCNC G5.2's clamped uniform vector (up to scale)"
    return None


def _zero(a, b, tol=1e-6):
    return all(abs(x - y) <= tol for x, y in zip(a, b))


def align_task(ours, theirs):
    """Walks our moves against the task's. For each of our NURBS: (index in
    ours, start, LinuxCNC's moves per biarc span or None, note). A span's
    moves are found by where they end: LinuxCNC's biarc i ends on its curve at
    u_i, which must be our curve's point there within 1e-5 mm."""
    out = []
    pos = [0.0, 0.0, 0.0]
    tpos = [0.0, 0.0, 0.0]
    j = 0
    lost = None

    def skip_zero():
        nonlocal j
        while j < len(theirs) and theirs[j]["kind"] == "line" and _zero(theirs[j]["end"], tpos):
            j += 1

    def at(q, p):
        return q < len(theirs) and not theirs[q]["rapid"] and _zero(theirs[q]["end"][:2], p, 1e-5)

    for idx, mv in enumerate(ours):
        if mv["kind"] == "nurbs":
            start = list(pos)
            pos = mv["end"]
            if lost:
                out.append((idx, start, None, lost))
                continue
            curve = Curve(mv)
            div = 4 * mv["control_points"]
            joints = curve.eval([(i + 1) / div for i in range(div)])
            spans = []
            for i in range(div):
                skip_zero()
                take = 2 if at(j + 1, joints[i]) else 1 if at(j, joints[i]) else 0
                spans.append(theirs[j: j + take])
                j += take
                if take:
                    tpos = theirs[j - 1]["end"]
            if not any(spans):
                lost = "LinuxCNC's moves do not pass through this curve's points"
                out.append((idx, start, None, lost))
                continue
            out.append((idx, start, spans, ""))
            continue
        if _zero(mv["end"], pos, 1e-9):
            continue  # zero-length: LinuxCNC's task drops it
        pos = mv["end"]
        if lost:
            continue
        skip_zero()
        if j < len(theirs) and _zero(theirs[j]["end"], mv["end"], 1e-5):
            tpos = theirs[j]["end"]
            j += 1
        elif j < len(theirs):
            lost = f"LinuxCNC's moves part from ours at our line {mv.get('line')}"
        else:
            lost = "LinuxCNC's moves end before this curve"
    return out


def nurbs_conformance(files, canon, workdir, program_timeout=PROGRAM_TIMEOUT_S, reuse=False):
    """The NURBS part: returns (per-file results, summary lines, ok)."""
    try:
        import numpy  # noqa: F401
        import geomdl  # noqa: F401
    except ImportError as e:
        return [], [f"NURBS paths not compared: {e} (pip install numpy geomdl==5.4.0)"], True
    if not reuse and not shutil.which("linuxcnc"):
        return [], ["NURBS paths not compared: no `linuxcnc` launcher (apt-get install linuxcnc-uspace)"], True
    ours_by_file = {}
    for f in files:
        ours, _ = run_ours(canon, f)
        if ours and any(m["kind"] == "nurbs" for m in ours):
            ours_by_file[f] = ours
    runs, err = run_task(list(ours_by_file), os.path.join(workdir, "as-written"), program_timeout, reuse)
    if err:
        return [], [f"NURBS paths not compared: {err}"], False
    results = []
    to_translate = []  # (file, nurbs index, Curve)
    for f, ours in ours_by_file.items():
        run = runs.get(f, {"moves": [], "errors": ["no output for this program"], "ended": False})
        refused = "; ".join(run["errors"]) or ("" if run["ended"] else "the program did not end")
        rec = {"file": display(f), "linuxcnc_refuses": refused or None, "curves": []}
        for idx, start, moves, note in align_task(ours, run["moves"]):
            mv = ours[idx]
            curve = Curve(mv)
            c = {"file": rec["file"], "line": mv["line"], "plane": mv["plane"], "order": curve.order,
                 "control_points": mv["control_points"]}
            if moves is not None:
                c["compared"] = "as written"
                if note:
                    c["note"] = note
                c.update(measure_curve(curve, moves, start))
            else:
                why = translatable(curve)
                c["not_as_written"] = "LinuxCNC: " + refused if refused else note
                if why:
                    c["compared"] = "no: " + why
                else:
                    c["compared"] = "pending"
                    to_translate.append((len(results), len(rec["curves"]), curve))
            rec["curves"].append(c)
        results.append(rec)
    # Second run: the curves LinuxCNC refused as written, as G5.2 in XY.
    programs = {}
    for ri, ci, curve in to_translate:
        programs.setdefault(ri, []).append((ci, curve))
    paths = {}
    tdir = os.path.join(workdir, "as-g5.2")
    os.makedirs(tdir, exist_ok=True)
    written = {}  # program text -> path: files that differ in Q only give the same program
    for ri, items in programs.items():
        text = g5_2_program([cv for _, cv in items])
        if text not in written:
            name = re.sub(r"[^A-Za-z0-9_.-]", "_", results[ri]["file"])
            written[text] = os.path.join(tdir, name)
            with open(written[text], "w") as fh:
                fh.write(text)
        paths[ri] = written[text]
    truns, err = run_task(list(written.values()), tdir, program_timeout, reuse)
    if err:
        return results, [f"translated curves not compared: {err}"], False
    measured = {}
    for ri, items in programs.items():
        run = truns.get(paths[ri], {"moves": [], "errors": ["no output"], "ended": False})
        ours = run_ours(canon, paths[ri])[0] or []
        aligned = align_task(ours, run["moves"])
        for (ci, curve), (idx, start, moves, note) in zip(items, aligned):
            c = results[ri]["curves"][ci]
            if moves is None:
                why = "; ".join(run["errors"]) or note
                c["compared"] = f"no: LinuxCNC did not run it as G5.2 either ({why})"
                continue
            c["compared"] = "as G5.2 in XY"
            c["g5_2_program"] = paths[ri]
            if note:
                c["note"] = note
            key = (paths[ri], idx)
            if key not in measured:
                measured[key] = measure_curve(Curve(ours[idx]), moves, start)
            c.update(measured[key])
    # Summary.
    lines = []
    ok = True
    compared = [c for r in results for c in r["curves"] if "deviation_max_mm" in c]
    for r in results:
        for c in r["curves"]:
            where = f"{r['file']}:{c['line']}"
            if "deviation_max_mm" in c:
                j = c.get("junction_max_mm")
                jtxt = f"joints {j * 1e6:.2f} nm" if j is not None else "joints not paired"
                bad = j is None or j > JUNCTION_TOL_MM or c["sampler_vs_geomdl_mm"] > 1e-9
                ok &= not bad
                miss = ""
                if c.get("spans_not_drawn"):
                    miss = (f"; LinuxCNC drew nothing for span(s) {compact(c['spans_not_drawn'])} of {c['spans']}: "
                            f"our curve there (and on the span after) up to {c['gap_max_mm'] * 1e3:.1f} um "
                            f"from its path")
                lines.append(f"{'FAIL ' if bad else 'ok   '} {where}: {c['compared']}, order {c['order']}, "
                             f"{c['control_points']} points, {c['linuxcnc_moves']} LinuxCNC moves "
                             f"({c['arcs']} arcs, {c['lines']} lines); {jtxt}; deviation "
                             f"{c['deviation_max_mm'] * 1e3:.3f} um at {c.get('deviation_max_at')}" + miss)
            else:
                lines.append(f"skip  {where}: {c['compared']} ({c.get('not_as_written')})")
    files_refused = [r for r in results if r["linuxcnc_refuses"]]
    reasons = {}
    for r in files_refused:
        reasons[r["linuxcnc_refuses"]] = reasons.get(r["linuxcnc_refuses"], 0) + 1
    as_written = [c for c in compared if c["compared"] == "as written"]
    translated = [c for c in compared if c["compared"] != "as written"]
    lines.append("")
    lines.append(f"{len(results)} programs with NURBS, {sum(len(r['curves']) for r in results)} curves; "
                 f"LinuxCNC refuses {len(files_refused)} of them as written:")
    for why, n in sorted(reasons.items(), key=lambda x: -x[1]):
        lines.append(f"  {n} x {why}")
    for label, group in (("as written", as_written), ("as G5.2 in XY", translated)):
        if not group:
            continue
        worst = max(group, key=lambda c: c["deviation_max_mm"])
        jmax = max((c.get("junction_max_mm") or 0.0) for c in group)
        devs = sorted(c["deviation_max_mm"] for c in group)
        lines.append(f"{len(group)} curves compared {label}: LinuxCNC's joints within {jmax * 1e6:.2f} nm of our "
                     f"curve; its arcs up to {worst['deviation_max_mm'] * 1e3:.3f} um from it "
                     f"({worst['file']}:{worst['line']}; median {devs[len(devs) // 2] * 1e3:.3f} um)")
        gaps = [c for c in group if c.get("spans_not_drawn")]
        if gaps:
            g = max(gaps, key=lambda c: c["gap_max_mm"])
            lines.append(f"  {len(gaps)} of them with spans LinuxCNC drew nothing for (straight or still spans): "
                         f"our curve up to {g['gap_max_mm']:.3f} mm from its path there ({g['file']}:{g['line']})")
    skipped = [c for r in results for c in r["curves"] if "deviation_max_mm" not in c]
    if skipped:
        lines.append(f"{len(skipped)} curves not compared:")
        why = {}
        for c in skipped:
            why[c["compared"]] = why.get(c["compared"], 0) + 1
        for w, n in sorted(why.items(), key=lambda x: -x[1]):
            lines.append(f"  {n} x {w}")
    return results, lines, ok


def self_test():
    """Checks the task-output parser, the alignment and the measurement on
    made-up LinuxCNC moves for an exact circle (no LinuxCNC needed)."""
    import numpy as np

    line = ("Issuing EMC_TRAJ_CIRCULAR_MOVE -- \t (  +221,+256,    +0,0.005446,0.144843,0.000000,0.000000,0.000000,"
            "0.000000,0.000000,0.000000,0.000000,1.929209,-0.000010,0.000000,0.000000,0.000000,1.000000,    -1,"
            "    +3,1.666667,4087.473614,10000000.000000,    +0,)")
    runs = parse_task_output(f"{MARK} BEGIN a.ngc\n{line}\n{MARK} ERROR oops\n{MARK} END a.ngc\n")
    mv = runs["a.ngc"]["moves"][0]
    assert runs["a.ngc"]["errors"] == ["oops"] and runs["a.ngc"]["ended"]
    assert mv["kind"] == "arc" and mv["end"] == [0.005446, 0.144843, 0.0] and not mv["ccw"], mv
    assert mv["centre"] == [1.929209, -0.00001, 0.0] and mv["turns"] == 0, mv
    # A quarter of the unit circle as a rational quadratic; "LinuxCNC" draws
    # each of its 12 spans as two arcs of the circle itself, centred at c.
    h = math.sqrt(0.5)
    rec = {"kind": "nurbs", "line": 1, "end": [0.0, 1.0, 0.0], "control_points": 3, "plane": 17, "degree": 2,
           "points": [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]], "weights": [1.0, h, 1.0],
           "knots": [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]}
    curve = Curve(rec)

    def arcs(c, skip=()):
        ends = curve.eval(np.linspace(0, 1, 25)[1:])
        out = []
        for k, e in enumerate(ends):
            if k // 2 in skip:
                continue
            out.append({"kind": "arc", "end": [e[0] + c[0], e[1] + c[1], 0.0], "centre": [c[0], c[1], 0.0],
                        "normal": [0.0, 0.0, 1.0], "ccw": True, "turns": 0, "rapid": False})
        return out

    ours = [{"kind": "rapid", "line": 0, "end": [1.0, 0.0, 0.0]}, rec]
    # Exact arcs; all shifted by 3 nm (the joints and the path 3 nm off); span 6
    # not drawn (the next arc starts where span 5 ended, still on the circle:
    # no gap); the last span not drawn (the path stops the last span's chord short).
    chord = float(np.linalg.norm(np.subtract(*curve.reference([11 / 12, 1.0]))))
    for shift, skip, gap in (((0.0, 0.0), (), None), ((3e-6, 0.0), (), None), ((0.0, 0.0), (5,), 0.0),
                             ((0.0, 0.0), (11,), chord)):
        theirs = [{"kind": "line", "end": [1.0 + shift[0], shift[1], 0.0], "rapid": True}] + arcs(shift, skip)
        ((_, start, spans, _),) = align_task(ours, theirs)
        m = measure_curve(curve, spans, start)
        d = math.hypot(*shift)
        assert abs(m["junction_max_mm"] - d) < 1e-9 and abs(m["deviation_max_mm"] - d) <= CHORD_SAG_MM, (shift, m)
        assert m.get("spans_not_drawn", []) == [k + 1 for k in skip], m
        assert gap is None or abs(m["gap_max_mm"] - gap) <= CHORD_SAG_MM, (gap, m)
    print("self-test passed")


CORPUS = "/work/shared/corpus/nurbs-linuxcnc"
NCFILES = "/usr/share/linuxcnc/ncfiles"


def display(path):
    """A short name: corpus/…, ncfiles/… or relative to the workspace."""
    for root, tag in ((CORPUS, "corpus"), (NCFILES, "ncfiles")):
        if path.startswith(root + "/"):
            return tag + path[len(root):]
    return os.path.relpath(path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    ap.add_argument("--canon", default=os.path.join(root, "target", "release", "examples", "canon"),
                    help="interpd's canon dump (cargo build --release -p gcode --example canon)")
    ap.add_argument("--json", help="write the per-file results here")
    ap.add_argument("--no-task", action="store_true", help="skip the NURBS paths (no LinuxCNC task run)")
    ap.add_argument("--workdir", help="keep LinuxCNC's configuration, output and G5.2 programs here "
                                      "(default: a temporary directory, removed)")
    ap.add_argument("--reuse", action="store_true",
                    help="measure again from LinuxCNC's output kept in --workdir by an earlier run")
    ap.add_argument("--program-timeout", type=float, default=PROGRAM_TIMEOUT_S,
                    help="seconds LinuxCNC may take for one program (default %(default)s)")
    ap.add_argument("--self-test", action="store_true",
                    help="check the parser and the measurement on made-up moves (no LinuxCNC needed)")
    ap.add_argument("files", nargs="*")
    a = ap.parse_args()
    if a.self_test:
        self_test()
        return
    if a.reuse and not a.workdir:
        sys.exit("--reuse needs --workdir")
    files = [os.path.abspath(f) for f in a.files] or sorted(glob.glob(NCFILES + "/*.ngc")) + sorted(
        glob.glob(os.path.join(root, "gcode", "tests", "programs", "*.ngc"))) + sorted(
        glob.glob(CORPUS + "/*/*.ngc"))
    if not os.path.exists(a.canon):
        sys.exit(f"{a.canon} missing: cargo build --release -p gcode --example canon")
    results = []
    covered = matched_files = moves_total = moves_matched = 0
    prefix_files = prefix_moves = prefix_matched = 0
    print("== moves: rs274 -g against interpd's canon dump")
    for f in files:
        theirs, reason_t, ok_t = run_rs274(f)
        ours, reason_o = run_ours(a.canon, f)
        name = display(f)
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
    summary = [f"{covered} of {len(files)} programs covered; {matched_files} match; "
               f"{moves_matched} of {moves_total} moves compared equal",
               f"{prefix_files} programs LinuxCNC stopped part way: {prefix_matched} of {prefix_moves} "
               f"moves before the stop compared equal"]
    print("\n" + "\n".join(summary))
    ok = matched_files == covered
    nurbs = []
    if not a.no_task:
        print("\n== NURBS paths: LinuxCNC's task (arcs) against interpd's exact curve")
        workdir = a.workdir or tempfile.mkdtemp(prefix="lcnc-conformance-")
        try:
            nurbs, lines, nurbs_ok = nurbs_conformance(files, a.canon, workdir, a.program_timeout, a.reuse)
        finally:
            if not a.workdir:
                shutil.rmtree(workdir, ignore_errors=True)
        print("\n".join(lines))
        ok &= nurbs_ok
        print("\n" + "\n".join(summary))
        print("\n".join(l for l in lines[lines.index("") + 1:] if l) if "" in lines else "")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"moves": results, "nurbs": nurbs}, fh, indent=1)
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()

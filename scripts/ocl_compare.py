#!/usr/bin/env python3
"""Compare `interpd plan raster` with OpenCAMLib's drop-cutter, side by side.

For one mesh and cutter this script
  1. runs `interpd plan raster ... --cl-json` (timed, wall clock),
  2. runs OpenCAMLib's BatchDropCutter at the same passes, sampling every
     --sample mm along each pass (timed, wall clock),
  3. interpolates our CL polylines at OpenCAMLib's points and reports the
     largest |dz| where both have a value.

Passes are at y = ymin + k * stepover (angle 0), as the planner places them.
OpenCAMLib leaves points the cutter cannot reach at their start height; those
are skipped, as are points outside our polylines.

    python3 -m venv out/venv && out/venv/bin/pip install opencamlib==2023.1.11
    cargo build --release -p interpd
    out/venv/bin/python scripts/ocl_compare.py --stl ../shared/corpus/meshes/terrain.stl \
        --tool ball:6 --stepover 0.5 --sample 0.1 --threads 2

Prints one JSON line: {"max_dz": ..., "ours_s": ..., "ocl_s": ..., ...}.
"""

import argparse
import bisect
import json
import os
import resource
import statistics
import struct
import subprocess
import sys
import tempfile
import time

import opencamlib as ocl

# OpenCAMLib's start height below the part: points left there did not touch.
BELOW = 1000.0
# A point within this of a polyline end counts as covered.
END_SLACK = 1e-9


def read_bounds(path):
    """x/y/z bounds of an STL (binary or ASCII) and its triangles as tuples."""
    data = open(path, "rb").read()
    tris = []
    if len(data) >= 84:
        n = struct.unpack("<I", data[80:84])[0]
        if 84 + 50 * n == len(data):
            for i in range(n):
                v = struct.unpack("<12f", data[84 + 50 * i: 84 + 50 * i + 48])
                tris.append((v[3:6], v[6:9], v[9:12]))
    if not tris:
        pts = [tuple(map(float, line.split()[1:4]))
               for line in data.decode("ascii", "replace").splitlines()
               if line.strip().startswith("vertex")]
        tris = [tuple(pts[i:i + 3]) for i in range(0, len(pts) - 2, 3)]
    xs = [p[0] for t in tris for p in t]
    ys = [p[1] for t in tris for p in t]
    zs = [p[2] for t in tris for p in t]
    return (min(xs), max(xs), min(ys), max(ys), min(zs), max(zs)), tris


def make_cutter(tool):
    parts = tool.split(":")
    d = float(parts[1])
    length = 100.0
    if parts[0] == "ball":
        return ocl.BallCutter(d, length)
    if parts[0] == "flat":
        return ocl.CylCutter(d, length)
    if parts[0] == "bull":
        return ocl.BullCutter(d, float(parts[2]), length)
    raise SystemExit(f"unknown tool {tool}")


def ocl_points(tris, tool, ys, xs, zmin, threads):
    """OCL's drop-cutter points and the wall and CPU seconds of
    BatchDropCutter.run() (CPU over all threads of this process). The
    STLSurf (and its kd-tree, built in run()) is rebuilt on every call."""
    # Triangles go in directly: OCL's STLReader takes binary files whose
    # header starts with "solid" for ASCII.
    surf = ocl.STLSurf()
    for a, b, c in tris:
        surf.addTriangle(ocl.Triangle(ocl.Point(*a), ocl.Point(*b), ocl.Point(*c)))
    bdc = ocl.BatchDropCutter()
    bdc.setSTL(surf)
    # Held here: the BatchDropCutter keeps only a pointer to it.
    cutter = make_cutter(tool)
    bdc.setCutter(cutter)
    bdc.setThreads(threads)
    for y in ys:
        for x in xs:
            bdc.appendPoint(ocl.CLPoint(x, y, zmin))
    c0, t0 = time.process_time(), time.perf_counter()
    bdc.run()
    dt, dc = time.perf_counter() - t0, time.process_time() - c0
    return [(p.x, p.y, p.z) for p in bdc.getCLPoints()], dt, dc


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_ours(cmd, env):
    """Runs our CLI once: (summary, wall s, CPU s of the child)."""
    c0, t0 = children_cpu(), time.perf_counter()
    out = subprocess.run(cmd, check=True, capture_output=True, text=True, env=env)
    return json.loads(out.stdout), time.perf_counter() - t0, children_cpu() - c0


def interp(polylines, x):
    """z of our pass at x (highest value if x hits a vertical step);
    polylines are (xs, points) pairs."""
    best = None
    for xs, line in polylines:
        if x < xs[0] - END_SLACK or x > xs[-1] + END_SLACK:
            continue
        i = bisect.bisect_left(xs, x)
        cands = []
        for j in (i - 1, i):
            if 0 <= j < len(line) - 1:
                a, b = line[j], line[j + 1]
                if a[2] is None or b[2] is None:
                    raise SystemExit(f"non-finite z in our path near x={x}: {a} {b}")
                if a[0] - END_SLACK <= x <= b[0] + END_SLACK:
                    if b[0] == a[0]:
                        cands.append(max(a[2], b[2]))
                    else:
                        t = min(1.0, max(0.0, (x - a[0]) / (b[0] - a[0])))
                        cands.append(a[2] + t * (b[2] - a[2]))
        if cands:
            z = max(cands)
            best = z if best is None else max(best, z)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stl", required=True)
    ap.add_argument("--tool", default="ball:6")
    ap.add_argument("--stepover", type=float, default=0.5)
    ap.add_argument("--sample", type=float, default=0.1)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--max-passes", type=int, default=0,
                    help="compare only every n-th pass so that OCL stays quick (0: all)")
    ap.add_argument("--interpd", default="target/release/interpd")
    ap.add_argument("--fixture", help="write the OCL points as a JSON fixture here")
    ap.add_argument("--overhang", type=float, default=None,
                    help="sample this far (mm) beyond the mesh's x range (default: the cutter radius)")
    ap.add_argument("--repeat", type=int, default=1,
                    help="time both this many times (alternating) and report min and median")
    args = ap.parse_args()

    (x0, x1, y0, y1, z0, z1), tris = read_bounds(args.stl)
    with tempfile.TemporaryDirectory() as tmp:
        cl = os.path.join(tmp, "cl.json")
        cmd = [args.interpd, "plan", "raster", "--stl", args.stl, "--tool", args.tool,
               "--stepover", repr(args.stepover), "--cl-json", cl, "--json", "--quiet"]
        env = dict(os.environ, RAYON_NUM_THREADS=str(args.threads))
        summary, ours_s, ours_cpu = run_ours(cmd, env)
        ours = [[([p[0] for p in line], line) for line in lines]
                for lines in json.load(open(cl))["passes"]]

    npass = len(ours)
    ks = list(range(npass))
    if args.max_passes and npass > args.max_passes:
        stride = -(-npass // args.max_passes)
        ks = ks[::stride]
    ys = [y0 + k * args.stepover for k in ks]
    r = float(args.tool.split(":")[1]) / 2
    over = r if args.overhang is None else args.overhang
    nx = int(round((x1 - x0 + 2 * over) / args.sample, 9)) + 1
    xs = [x0 - over + i * args.sample for i in range(nx)]
    load_before = os.getloadavg()
    pts, ocl_s, ocl_cpu = ocl_points(tris, args.tool, ys, xs, z0 - BELOW, args.threads)
    runs = {"ours_wall": [ours_s], "ours_cpu": [ours_cpu], "ours_plan": [summary["plan-s"]],
            "ocl_wall": [ocl_s], "ocl_cpu": [ocl_cpu]}
    for _ in range(args.repeat - 1):
        # Repeats time planning only (no CL dump), as OCL's run() is.
        i = cmd.index("--cl-json")
        sm, w, c = run_ours(cmd[:i] + cmd[i + 2:], env)
        runs["ours_wall"].append(w)
        runs["ours_cpu"].append(c)
        runs["ours_plan"].append(sm["plan-s"])
        _, w, c = ocl_points(tris, args.tool, ys, xs, z0 - BELOW, args.threads)
        runs["ocl_wall"].append(w)
        runs["ocl_cpu"].append(c)
    load_after = os.getloadavg()
    # Timings first, so they survive a failure of the comparison below.
    print(json.dumps({"timings": runs, "load": [load_before, load_after]}), file=sys.stderr)

    max_dz, worst, compared, missing = 0.0, None, 0, 0
    fixture = []
    for idx, (x, y, z) in enumerate(pts):
        if z <= z0 - BELOW + 1e-6:
            continue
        k = ks[idx // nx]
        zz = interp(ours[k], x)
        if zz is None:
            missing += 1
            continue
        compared += 1
        fixture.append([round(x, 9), round(y, 9), z])
        dz = abs(zz - z)
        if dz > max_dz:
            max_dz, worst = dz, (x, y, z, zz)
    res = {
        "stl": os.path.basename(args.stl), "tool": args.tool, "stepover": args.stepover,
        "sample": args.sample, "passes_compared": len(ks), "ocl_points": len(pts),
        "compared": compared, "not_covered": missing, "max_dz": max_dz, "worst": worst,
        "ours_s": round(ours_s, 3), "ours_plan_s": round(summary["plan-s"], 3),
        "ours_read_s": round(summary["read-s"], 3), "ocl_s": round(ocl_s, 3),
        "speedup_plan": round(ocl_s / summary["plan-s"], 1) if summary["plan-s"] > 0 else None,
        "speedup_wall": round(ocl_s / ours_s, 1), "threads": args.threads,
        "ocl_version": ocl.version(), "triangles": summary["stats"]["triangles"],
        "our_points": summary["stats"]["points"],
        "load_avg_before": load_before, "load_avg_after": load_after,
    }
    for k, v in runs.items():
        res[k + "_min"] = round(min(v), 3)
        res[k + "_median"] = round(statistics.median(v), 3)
    res["repeats"] = args.repeat
    res["speedup_cpu_min"] = round(min(runs["ocl_cpu"]) / min(runs["ours_cpu"]), 1)
    res["speedup_wall_min"] = round(min(runs["ocl_wall"]) / min(runs["ours_wall"]), 1)
    print(json.dumps(res))
    if args.fixture:
        json.dump({"stl": os.path.basename(args.stl), "tool": args.tool,
                   "stepover": args.stepover, "ocl_version": ocl.version(),
                   "points": fixture}, open(args.fixture, "w"), indent=0)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/bin/sh
# Side by side: `interpd plan raster` against OpenCAMLib 2023.1.11's
# BatchDropCutter on terrain.stl (75,586 triangles), 6 mm ball, 0.5 mm
# step-over, 2 threads. OCL drops the cutter every 0.1 mm along each of our
# passes over the mesh's x range (150 passes x 750 points = 112,500 points);
# we plan the same passes to a 1e-5 mm chord tolerance. Both are timed
# REPEAT times, alternating (wall and CPU), and max |dz| of our polylines at
# OCL's points is reported. One JSON line on stdout.
#
#   python3 -m venv out/venv && out/venv/bin/pip install opencamlib==2023.1.11
#   cargo build --release -p interpd
#   scripts/raster_vs_ocl.sh [STL] [REPEAT]
set -eu
stl=${1:-../shared/corpus/meshes/terrain.stl}
repeat=${2:-3}
py=${PY:-out/venv/bin/python}
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
"$py" scripts/ocl_compare.py --stl "$stl" --tool ball:6 --stepover 0.5 \
  --sample 0.1 --overhang 0 --threads 2 --repeat "$repeat"
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)" >&2

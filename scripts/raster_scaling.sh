#!/bin/sh
# Raster planning time and peak memory against mesh size: generated height
# fields (scripts/gen_terrain_stl.py, a regular grid over 75 x 75 mm), 6 mm
# ball, 0.5 mm step-over, 2 threads. One line per mesh: the CLI's JSON
# summary (triangles, points, read-s, plan-s) followed by the process's user
# and system CPU seconds, wall seconds and peak RSS from /usr/bin/time.
#   scripts/raster_scaling.sh [SIZES...]   (needs PY with numpy, a release build)
set -eu
py=${PY:-out/venv/bin/python}
sizes=${*:-75000 250000 500000 1000000 2000000}
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
for n in $sizes; do
  "$py" scripts/gen_terrain_stl.py "$n" "out/gen_$n.stl" > /dev/null
  RAYON_NUM_THREADS=2 /usr/bin/time -o out/scaling_time.txt \
    -f "user-s %U sys-s %S wall-s %e peak-rss-kb %M" \
    target/release/interpd plan raster --stl "out/gen_$n.stl" --tool ball:6 \
    --stepover 0.5 --json --quiet | tr -d '\n'
  echo " $(cat out/scaling_time.txt)"
  rm -f "out/gen_$n.stl"
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)" >&2

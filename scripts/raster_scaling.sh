#!/bin/sh
# Raster planning time and peak memory against mesh size (generated height
# fields), 6 mm ball, 0.5 mm step-over, 2 threads.
#   scripts/raster_scaling.sh  (needs out/venv with numpy, a release build)
set -eu
for n in 75000 250000 1000000 2000000; do
  out/venv/bin/python scripts/gen_terrain_stl.py "$n" "out/gen_$n.stl" > /dev/null
  RAYON_NUM_THREADS=2 /usr/bin/time -f "peak-rss-kb %M wall-s %e" \
    target/release/interpd plan raster --stl "out/gen_$n.stl" --tool ball:6 --stepover 0.5 --json --quiet
  rm -f "out/gen_$n.stl"
done

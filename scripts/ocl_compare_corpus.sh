#!/bin/sh
# Accuracy of `interpd plan raster` against OpenCAMLib on every corpus mesh,
# for a ball, a flat and a bull cutter. One JSON line per run.
#   scripts/ocl_compare_corpus.sh [CORPUS_DIR] [MAX_PASSES] > out/accuracy.jsonl
set -eu
dir=${1:-../shared/corpus/meshes}
max=${2:-12}
py=${PY:-out/venv/bin/python}
for stl in "$dir"/*.stl; do
  for tool in ball:6 flat:6 bull:6:1; do
    "$py" scripts/ocl_compare.py --stl "$stl" --tool "$tool" --max-passes "$max"
  done
done

#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# `make demo`: generates the default simulated street (cleanmap-sim), removes its moving objects
# (cleanmap), scores the result with pictures (cleanmap-eval), and says where everything is.
# DEMO_INPUT=<KITTI folder or rawlog> runs cleanmap on that input instead of the simulation.
set -euo pipefail
build=$1 input=${2:-} out=$3
mkdir -p "$out"
if [[ -z $input ]]; then
  input=$out/sim_default
  echo "demo: generating the default scenario (datasets/scenarios/default.ini) into $input"
  "$build/apps/cleanmap-sim" -o "$input" --threads "$(nproc)"
fi
[[ -e $input ]] || { echo "demo: $input does not exist (DEMO_INPUT)"; exit 1; }
name=cleaned_$(basename "$input" .rawlog)
"$build/apps/cleanmap-info" "$input"
"$build/apps/cleanmap" "$input" -o "$out/$name" --threads "$(nproc)"
evaluated=0
if [[ -d $input/labels ]]; then
  "$build/apps/cleanmap-eval" "$input" "$out/$name" --report "$out/$name/evaluation"
  evaluated=1
fi
echo
echo "demo: results in $out"
echo "  input              : $input$([[ -f $input/sequence.rawlog ]] && echo " (MRPT rawlog: $input/sequence.rawlog)")"
echo "  cleaned static map : $out/$name/static_map.ply (every static point: static_map_full.ply)"
echo "  moving points      : $out/$name/dynamic.ply"
echo "  per-scan labels    : $out/$name/labels/"
echo "  for MRPT           : SceneViewer3D $out/$name/static_map.3Dscene; cleaned.rawlog, labelled.rawlog, static_map.simplemap (doc/MRPT.md)"
echo "  ground model layer : $out/$name/ground_model.ply (.txt); map plugins: $build/libs/maps/libcleanmap_maps.so"
echo "  run report         : $out/$name/report.md (and report.json)"
if [[ $evaluated == 1 ]]; then
  echo "  evaluation         : $out/$name/evaluation/report.md"
  echo "  pictures           : $out/$name/evaluation/bev_*.png (TP red, FP orange, FN blue), map_overview.png"
fi

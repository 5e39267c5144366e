#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# `make demo`: runs cleanmap on the default input (a labelled KITTI folder), converts it to an
# MRPT rawlog too, and says where everything is.
set -euo pipefail
build=$1 input=$2 out=$3
mkdir -p "$out"
if [[ ! -d "$input" ]]; then
  vlp=/usr/share/mrpt/datasets/test_velodyne_VLP16.rawlog
  echo "demo: $input not found (set DEMO_INPUT=<KITTI folder or rawlog>); summarising $vlp instead"
  "$build/apps/cleanmap-info" "$vlp"
  exit 0
fi
name=$(basename "$input")
"$build/apps/cleanmap-info" "$input"
"$build/apps/cleanmap" "$input" -o "$out/$name" --threads "$(nproc)"
"$build/apps/cleanmap-kitti2rawlog" "$input" "$out/$name.rawlog"
echo
echo "demo: results in $out"
echo "  cleaned static map : $out/$name/static_map.ply (every static point: static_map_full.ply)"
echo "  moving points      : $out/$name/dynamic.ply"
echo "  per-scan labels    : $out/$name/labels/"
echo "  report             : $out/$name/report.md (and report.json)"
echo "  MRPT rawlog        : $out/$name.rawlog  (RawLogViewer $out/$name.rawlog)"

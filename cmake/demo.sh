#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# `make demo`: converts the default KITTI input to an MRPT rawlog and summarises both.
# (The full moving-object pipeline joins here when it lands; see README.)
set -euo pipefail
build=$1 input=$2 out=$3
mkdir -p "$out"
if [[ -d "$input" ]]; then
  name=$(basename "$input")
  "$build/apps/cleanmap-info" "$input"
  "$build/apps/cleanmap-kitti2rawlog" "$input" "$out/$name.rawlog"
  "$build/apps/cleanmap-info" "$out/$name.rawlog"
  rawlog-edit --info -i "$out/$name.rawlog" 2>/dev/null | grep -E "objects|Sensor|timestamp" || true
  echo
  echo "demo: results in $out"
  echo "      $out/$name.rawlog  (open with: RawLogViewer $out/$name.rawlog)"
else
  vlp=/usr/share/mrpt/datasets/test_velodyne_VLP16.rawlog
  echo "demo: $input not found (set DEMO_INPUT=<KITTI folder>); summarising MRPT's $vlp instead"
  "$build/apps/cleanmap-info" "$vlp"
fi

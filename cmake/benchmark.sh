#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# `make benchmark`: I/O, simulator and per-stage benchmarks (issue #16), a long simulated run
# (LONG_SCANS scans, default 1000; issue #15 used 10000: memory and time per scan must stay
# flat), then per labelled set a Release run of cleanmap (2 threads) and its evaluation
# (DESIGN §5), one summary table, and the ROC sweep. Results in $OUT.
# usage: benchmark.sh BUILD_DIR DATA_DIR OUT [ROC=1]
set -euo pipefail
build=$1 data=$2 out=$3 roc=${4:-1}
threads=${THREADS:-2}
mkdir -p "$out"
echo "== machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"
# The instruction set of the build (CLEANMAP_ARCH, README): timings of different builds differ.
march=$(grep -o -m1 -- '-march=[^ "]*' "$build/compile_commands.json" 2>/dev/null || true)
echo "== build: ${march:-portable x86-64}"
"$build/tests/benchmarks/cleanmap-bench-io" --data "$data"
"$build/tests/benchmarks/cleanmap-bench-sim"
"$build/tests/benchmarks/cleanmap-bench-stages" --data "$data" | tee "$out/stages.txt"
"$build/tests/benchmarks/cleanmap-bench-long" --scans "${LONG_SCANS:-1000}" --every 250 \
  --threads "$threads" | tee "$out/long_run.txt"
jsons=()
for set in kitti_city kitti_highway kitti_residential; do
  [[ -d $data/$set ]] || { echo "benchmark: $data/$set not found, skipped"; continue; }
  "$build/apps/cleanmap" "$data/$set" -o "$out/$set/run" --threads "$threads" --quiet
  "$build/apps/cleanmap-eval" "$data/$set" "$out/$set/run" --json --report "$out/$set/eval" >"$out/$set/eval.json"
  jsons+=("$out/$set/eval.json")
done
[[ ${#jsons[@]} -gt 0 ]] || { echo "benchmark: no labelled set in $data"; exit 1; }
"$build/apps/cleanmap-eval" summary "${jsons[@]}" | tee "$out/summary.md"
if [[ $roc == 1 ]]; then
  for set in kitti_city kitti_highway kitti_residential; do
    [[ -d $data/$set ]] || continue
    "$build/apps/cleanmap-eval" roc "$data/$set" -o "$out/$set/roc" --threads "$threads"
  done
fi
echo "benchmark: summary $out/summary.md; per set: $out/<set>/eval/report.md (pictures), $out/<set>/roc/roc.md"

#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# End-to-end checks of cleanmap + cleanmap-eval on a short stretch of kitti_city: --json keys,
# the report folder with pictures, roc, summary, and one clear error line per bad input.
# usage: eval_test.sh BIN_DIR DATA_DIR SCRATCH
set -uo pipefail
bin=$1 data=${CLEANMAP_DATA_DIR:-$2} scratch=$3  # the env variable wins, as for the unit tests
rm -rf "$scratch" && mkdir -p "$scratch"
source "$(dirname "$0")/common.sh"

city=$data/kitti_city
require_dataset "$city"

"$bin/cleanmap" "$city" -o "$scratch/run" --first 8 --last 14 --quiet >/dev/null || fail "cleanmap run failed"
json=$("$bin/cleanmap-eval" "$city" "$scratch/run" --first 8 --last 14 --json --report "$scratch/report") ||
  fail "cleanmap-eval failed"
for k in precision recall iou SA DA AA HA runtime objects; do
  grep -q "\"$k\"" <<<"$json" || fail "--json lacks $k"
done
# Sanity of the numbers: the moving car is mostly found, the static map mostly kept.
sa=$(grep -o '"SA": [0-9.e-]*' <<<"$json" | cut -d' ' -f2)
awk -v s="$sa" 'BEGIN { exit !(s > 0.9 && s <= 1) }' || fail "SA $sa not in (0.9, 1]"
[[ -s $scratch/report/report.md && -s $scratch/report/bev_000010.png && -s $scratch/report/map_overview.png ]] ||
  fail "report folder incomplete"
# The report folder is written as a whole: a rerun over fewer scans leaves none of the earlier
# pictures; a run that fails (here a full disk at the map's overview) leaves the earlier report as
# it was and nothing beside it; a folder that holds no report (the run's own) is refused untouched.
"$bin/cleanmap-eval" "$city" "$scratch/run" --first 10 --last 12 --report "$scratch/report" >/dev/null ||
  fail "cleanmap-eval over fewer scans failed"
[[ -s $scratch/report/bev_000011.png && ! -e $scratch/report/bev_000008.png ]] ||
  fail "the report of scans 10-12 is not the one folder: $(ls "$scratch/report" | tr '\n' ' ')"
before=$(cd "$scratch/report" && md5sum -- *)
expect_error 1 "$scratch/report/map_overview.png: write failed" \
  full_disk 100 "$bin/cleanmap-eval" "$city" "$scratch/run" --first 8 --last 14 --report "$scratch/report"
[[ $(cd "$scratch/report" && md5sum -- *) == "$before" ]] || fail "a failed report changed the earlier one"
ls -a "$scratch" | grep -q staging && fail "a failed report left its staging folder"
run_report=$(md5sum <"$scratch/run/report.json")
expect_error 1 "the output folder is the input folder" "$bin/cleanmap-eval" "$city" "$scratch/run" --report "$scratch/run"
[[ $(md5sum <"$scratch/run/report.json") == "$run_report" ]] || fail "--report into the run changed its report.json"
mkdir -p "$scratch/mine" && echo keep >"$scratch/mine/notes.txt"
expect_error 1 "holds no report of cleanmap-eval" "$bin/cleanmap-eval" "$city" "$scratch/run" --report "$scratch/mine"
# An earlier report is replaced, but not when it holds what is scored.
cp -r "$scratch/run" "$scratch/report/run"
expect_error 1 "holds the input" "$bin/cleanmap-eval" "$city" "$scratch/report/run" --report "$scratch/report"
[[ -f $scratch/report/run/report.json ]] || fail "a refused report touched the result inside it"
rm -rf "$scratch/report/run"
expect_error 1 "holds no ROC sweep" "$bin/cleanmap-eval" roc "$city" -o "$scratch/run" --first 9 --last 11
printf '%s\n' "$json" >"$scratch/a.json"
"$bin/cleanmap-eval" summary "$scratch/a.json" "$scratch/a.json" | grep -q "all (summed counts)" ||
  fail "summary has no overall row"
"$bin/cleanmap-eval" roc "$city" -o "$scratch/roc" --first 9 --last 11 --sigma-r 0.15 --sigma-theta 0.0035 >/dev/null 2>&1 ||
  fail "roc failed"
[[ -s $scratch/roc/roc.png && -s $scratch/roc/roc.md ]] || fail "roc outputs missing"

# Bad inputs: exit 1 with one line naming the file, or exit 2 for the command line.
expect_error 1 "no such result" "$bin/cleanmap-eval" "$city" "$scratch/missing"
expect_error 1 "directory does not exist" "$bin/cleanmap-eval" "$scratch/nogt" "$scratch/run"
printf 'garbage' >"$scratch/map.pcd"
expect_error 1 "map.pcd" "$bin/cleanmap-eval" "$city" "$scratch/map.pcd"
expect_error 1 "needs the sequence's camera" "$bin/cleanmap-eval" "$city" "$scratch/run" --camera-fov
expect_error 2 "unknown option" "$bin/cleanmap-eval" "$city" "$scratch/run" --bogus
expect_error 2 "--radius" "$bin/cleanmap-eval" "$city" "$scratch/run" --radius x
expect_error 2 "--sigma-r" "$bin/cleanmap-eval" roc "$city" -o "$scratch/r2" --sigma-r 0.1,abc

expect_error 1 "output folder is the input folder" "$bin/cleanmap" "$scratch/run" -o "$scratch/run/"
[[ $fails -eq 0 ]] && echo "eval_test: all checks passed"
finish

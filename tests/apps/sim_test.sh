#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# End-to-end checks of cleanmap-sim: a short default sequence that our reader and MRPT's
# rawlog-edit accept, the same bytes for 1 and 2 threads, and one clear error line per bad input.
# usage: sim_test.sh BIN_DIR SCRATCH
set -uo pipefail
bin=$1 scratch=$2
rm -rf "$scratch" && mkdir -p "$scratch"
source "$(dirname "$0")/common.sh"

"$bin/cleanmap-sim" -o "$scratch/a" --frames 3 --threads 2 >/dev/null 2>&1 || fail "generation failed"
"$bin/cleanmap-sim" -o "$scratch/b" --frames 3 --threads 1 --no-rawlog >/dev/null 2>&1 || fail "generation failed"
for f in velodyne/000002.bin labels/000002.label image_2/000001.png poses.txt calib.txt objects.json; do
  [[ -s $scratch/a/$f ]] || fail "missing $f"
  cmp -s "$scratch/a/$f" "$scratch/b/$f" || fail "$f differs between 1 and 2 threads"
done
info=$("$bin/cleanmap-info" "$scratch/a") || fail "cleanmap-info cannot read the sequence"
grep -q "poses:   3 of 3" <<<"$info" || fail "cleanmap-info: $info"
if command -v rawlog-edit >/dev/null; then
  grep -Eq "LIDAR / +3 " <<<"$(rawlog-edit --info -i "$scratch/a/sequence.rawlog" 2>/dev/null)" ||
    fail "rawlog-edit does not see 3 LIDAR observations"
fi

# [ego] odometry: sequence.rawlog carries wheel odometry (CObservationOdometry) per frame.
sed 's/^\[ego\]/[ego]\nodometry = 0.01/' "$(dirname "$0")/../../datasets/scenarios/default.ini" >"$scratch/odo.ini"
"$bin/cleanmap-sim" "$scratch/odo.ini" -o "$scratch/odo" --frames 3 --no-images >/dev/null 2>&1 ||
  fail "generation with odometry failed"
grep -q "odometry: 3 of 3 scans" <<<"$("$bin/cleanmap-info" "$scratch/odo/sequence.rawlog")" ||
  fail "cleanmap-info sees no odometry in sequence.rawlog"
grep -q "odometry" <<<"$("$bin/cleanmap-info" "$scratch/a/sequence.rawlog")" &&
  fail "odometry written without [ego] odometry"
if command -v rawlog-edit >/dev/null; then
  grep -Eq "ODOMETRY / +3 " <<<"$(rawlog-edit --info -i "$scratch/odo/sequence.rawlog" 2>/dev/null)" ||
    fail "rawlog-edit does not see 3 ODOMETRY observations"
fi

printf '[scenario]\nframes = many\n' >"$scratch/bad.ini"
expect_error 1 "bad.ini:2" "$bin/cleanmap-sim" "$scratch/bad.ini" -o "$scratch/c"
expect_error 1 "missing.ini" "$bin/cleanmap-sim" "$scratch/missing.ini" -o "$scratch/c"
expect_error 2 "need -o" "$bin/cleanmap-sim"
expect_error 2 "unknown option" "$bin/cleanmap-sim" -o "$scratch/c" --fast

# The output folder is written as a whole: an earlier sequence is replaced (no stale frames), a
# foreign folder refused, and a full disk (a file-size limit) leaves the earlier one as it was.
"$bin/cleanmap-sim" -o "$scratch/a" --frames 2 --threads 2 --no-images >/dev/null 2>&1 || fail "regeneration failed"
[[ $(ls "$scratch/a/velodyne" | wc -l) -eq 2 && ! -e $scratch/a/image_2 ]] || fail "stale files of the earlier sequence survived"
mkdir -p "$scratch/mine" && echo keep >"$scratch/mine/notes.txt"
expect_error 1 "holds no cleanmap-sim sequence" "$bin/cleanmap-sim" -o "$scratch/mine" --frames 2
[[ -f $scratch/mine/notes.txt ]] || fail "a foreign folder was touched"
expect_error 1 "exists and is not a folder" "$bin/cleanmap-sim" -o "$scratch/mine/notes.txt" --frames 2
cp -r "$scratch/a" "$scratch/a.before"
expect_error 1 "write failed (disk full?)" full_disk 64 "$bin/cleanmap-sim" -o "$scratch/a" --frames 3 --threads 2
diff -r "$scratch/a" "$scratch/a.before" >/dev/null || fail "a failed generation touched the earlier sequence"
[[ $(ls -A "$scratch" | grep -c staging) -eq 0 ]] || fail "a failed generation left its staging folder"

# datasets/perturb_scenarios.py composes variants with '+' (a, then b): a 3-scan scene as an
# OS1-64 with another noise draw is simulated, run and scored; two lidars at once are refused.
perturb=$(dirname "$0")/../../datasets/perturb_scenarios.py
line=$(python3 "$perturb" --apps "$bin" -o "$scratch/perturb" --scenarios ground_curb_ramp \
  --variants os1_64+seed 2>&1) || fail "perturb_scenarios.py os1_64+seed: $line"
[[ $line == "ground_curb_ramp "*" os1_64+seed P "*" SA "* ]] || fail "perturb_scenarios.py printed '$line'"
ini=$scratch/perturb/ground_curb_ramp_os1_64+seed.ini
{ grep -q "^model = os1-64" "$ini" && grep -q "^seed = 11" "$ini"; } ||
  fail "os1_64+seed did not apply both: $(grep -E 'model|seed' "$ini" | tr '\n' ' ')"
expect_error 1 "vlp16+hdl32: more than one lidar" python3 "$perturb" --apps "$bin" \
  -o "$scratch/perturb" --variants vlp16+hdl32
# Two ways compared on one simulated line: a build against itself gives byte-identical labels
# and clean map; a crop of 10 m instead of 30 leaves the points between unclassified (label 0;
# the clean map reaches static_map.radius either way).
line=$(python3 "$perturb" --apps "$bin" --against "$bin" -o "$scratch/perturb" \
  --scenarios ground_curb_ramp --variants os1_64 2>&1) || fail "perturb_scenarios.py --against: $line"
grep -q "^ground_curb_ramp .* | same$" <<<"$line" && grep -q "^1 lines compared, 0 differ$" <<<"$line" ||
  fail "a build against itself: '$line'"
sed 's/^filter.crop_tau *=.*/filter.crop_tau = 10/' "$(dirname "$0")/../../config/cleanmap.ini" \
  >"$scratch/crop10.ini"
line=$(python3 "$perturb" --apps "$bin" --against-config "$scratch/crop10.ini" \
  -o "$scratch/perturb" --scenarios ground_curb_ramp --variants os1_64 2>&1) ||
  fail "perturb_scenarios.py --against-config: $line"
grep -Eq "^ground_curb_ramp .* \| labels (and map )?differ$" <<<"$line" &&
  grep -q "^1 lines compared, 1 differ$" <<<"$line" || fail "a 10 m crop against 30 m: '$line'"

[[ $fails -eq 0 ]] && echo "sim_test: all checks passed"
finish

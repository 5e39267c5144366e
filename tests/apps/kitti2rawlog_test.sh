#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# End-to-end checks of cleanmap-kitti2rawlog: a conversion MRPT's own tools accept, and one clear
# error line plus a non-zero exit for each kind of bad input.
# usage: kitti2rawlog_test.sh BIN_DIR DATA_DIR SCRATCH
set -uo pipefail
bin=$1 data=${CLEANMAP_DATA_DIR:-$2} scratch=$3  # the env variable wins, as for the unit tests
rm -rf "$scratch" && mkdir -p "$scratch"
source "$(dirname "$0")/common.sh"

city=$data/kitti_city
require_dataset "$city"

# A good conversion, checked by MRPT's rawlog-edit.
"$bin/cleanmap-kitti2rawlog" "$city" "$scratch/city.rawlog" >/dev/null || fail "conversion failed"
info=$(rawlog-edit --info -i "$scratch/city.rawlog" 2>/dev/null)
grep -Eq "LIDAR / +22 " <<<"$info" || fail "rawlog-edit does not see 22 LIDAR observations: $info"
grep -Eq "POSE / +22 " <<<"$info" || fail "rawlog-edit does not see 22 POSE observations"
"$bin/cleanmap-kitti2rawlog" "$city" "$scratch/city_ext.rawlog" --external >/dev/null || fail "external"
grep -Eq "LIDAR / +22 " <<<"$(rawlog-edit --info -i "$scratch/city_ext.rawlog" 2>/dev/null)" ||
  fail "rawlog-edit cannot read the external rawlog"

# As a simplemap (a SLAM's keyframes, at KITTI's poses): cleanmap-info sees a keyframe per scan.
out=$("$bin/cleanmap-kitti2rawlog" "$city" "$scratch/city.simplemap") || fail "simplemap conversion failed"
[[ $out == *"22 keyframes, 22 poses"* ]] || fail "simplemap conversion said: $out"
info=$("$bin/cleanmap-info" "$scratch/city.simplemap") || fail "cleanmap-info cannot read the simplemap"
[[ $info == *"MRPT simplemap"* && $info == *"22 scans"* ]] || fail "cleanmap-info on the simplemap: $info"

# Bad inputs.
mk() {  # mk NAME: a 3-scan copy of kitti_city (links) to spoil
  local d=$scratch/$1; mkdir -p "$d/velodyne"
  for s in 000000 000001 000002; do ln -s "$city/velodyne/$s.bin" "$d/velodyne/$s.bin"; done
  head -3 "$city/poses.txt" >"$d/poses.txt"; cp "$city/calib.txt" "$d/calib.txt"
  echo "$d"
}
expect_error 1 "directory does not exist" "$bin/cleanmap-kitti2rawlog" "$scratch/nope" "$scratch/o.rawlog"
d=$(mk truncated); rm "$d/velodyne/000001.bin"; head -c 1000 "$city/velodyne/000001.bin" >"$d/velodyne/000001.bin"
expect_error 1 "000001.bin: truncated scan" "$bin/cleanmap-kitti2rawlog" "$d" "$scratch/o.rawlog"
d=$(mk posecount); head -2 "$city/poses.txt" >"$d/poses.txt"
expect_error 1 "has 2 poses but the sequence has 3 scans" "$bin/cleanmap-kitti2rawlog" "$d" "$scratch/o.rawlog"
d=$(mk calibkey); echo "P0: 1 0 0 0 0 1 0 0 0 0 1 0" >"$d/calib.txt"
expect_error 1 "missing calibration key 'Tr'" "$bin/cleanmap-kitti2rawlog" "$d" "$scratch/o.rawlog"
d=$(mk noposes); rm "$d/poses.txt"
expect_error 1 "noposes: has no poses (poses.txt, or oxts/ for a raw drive): a simplemap's keyframes need them" "$bin/cleanmap-kitti2rawlog" "$d" "$scratch/o.simplemap"
[[ -e $scratch/o.simplemap ]] && fail "a failed conversion left $scratch/o.simplemap"
[[ -e $scratch/o.rawlog ]] && fail "a failed conversion left $scratch/o.rawlog"
ls "$scratch" | grep -q '\.tmp\.' && fail "a temporary file was left behind"

# Empty scans (0 bytes) are kept and counted, as in every app (README, "Bad input").
d=$(mk empty); rm "$d/velodyne/000002.bin"; : >"$d/velodyne/000002.bin"
out=$("$bin/cleanmap-kitti2rawlog" "$d" "$scratch/empty.rawlog") || fail "an empty scan stopped the conversion"
[[ "$out" == *"3 scans"*"1 empty scans kept"* ]] || fail "empty scan not reported: $out"

# NaN points: dropped, counted, reported; the rawlog holds only finite points.
d=$(mk nan); rm "$d/velodyne/000000.bin"
python3 - "$city/velodyne/000000.bin" "$d/velodyne/000000.bin" <<'PY'
import struct, sys
b = bytearray(open(sys.argv[1], 'rb').read())
for i in (0, 7, 100):
    b[16*i:16*i+4] = struct.pack('<f', float('nan'))
open(sys.argv[2], 'wb').write(b)
PY
out=$("$bin/cleanmap-kitti2rawlog" "$d" "$scratch/nan.rawlog") || fail "NaN scan not converted"
[[ "$out" == *"dropped 3 NaN/inf points"* ]] || fail "NaN points not reported: $out"
info=$("$bin/cleanmap-info" "$scratch/nan.rawlog") || fail "cleanmap-info failed on nan.rawlog"

# A truncated rawlog is reported by the reader.
cp "$scratch/city.rawlog" "$scratch/cut.rawlog"; truncate -s 3000000 "$scratch/cut.rawlog"
expect_error 1 "truncated" "$bin/cleanmap-info" "$scratch/cut.rawlog"

# Usage errors exit 2.
"$bin/cleanmap-kitti2rawlog" >/dev/null 2>&1; [[ $? -eq 2 ]] || fail "no arguments should exit 2"
"$bin/cleanmap-kitti2rawlog" a b --bogus >/dev/null 2>&1; [[ $? -eq 2 ]] || fail "unknown option should exit 2"
"$bin/cleanmap-kitti2rawlog" --help | grep -q -- "--external" || fail "--help does not explain --external"

[[ $fails -eq 0 ]] && echo "all kitti2rawlog checks passed"
finish

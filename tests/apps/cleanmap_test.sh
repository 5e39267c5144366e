#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# End-to-end checks of cleanmap's output folder and input rules, on a short simulated sequence (no
# external data): atomic publication, real SIGINT / SIGTERM, refusing a foreign folder, empty and
# all-NaN scans in every app, and one clear error line per bad input.
# usage: cleanmap_test.sh BIN_DIR SCRATCH
set -uo pipefail
bin=$1 scratch=$2
rm -rf "$scratch" && mkdir -p "$scratch"
source "$(dirname "$0")/common.sh"

"$bin/cleanmap-sim" -o "$scratch/seq" --frames 24 --threads 2 --no-images >/dev/null 2>&1 || fail "sim failed"
seq=$scratch/seq

# A full run, then a shorter one into the same folder: replaced as a whole, no stale labels.
"$bin/cleanmap" "$seq" -o "$scratch/out" --quiet >/dev/null || fail "first run failed"
[[ $(ls "$scratch/out/labels" | wc -l) -eq 24 ]] || fail "expected 24 label files"
cp -r "$scratch/out" "$scratch/clean"  # a default run, scored against one without cleaning below
# A simplemap (a SLAM's keyframes; here the run's own) is an input too: its scans at their
# keyframes' poses.
"$bin/cleanmap" "$scratch/out/static_map.simplemap" -o "$scratch/from_sm" --quiet --no-mrpt-outputs >/dev/null ||
  fail "a simplemap did not run"
[[ $(ls "$scratch/from_sm/labels" | wc -l) -eq 24 ]] || fail "a simplemap: expected 24 label files"
python3 - "$scratch/out/poses.txt" "$scratch/from_sm/poses.txt" <<'PY' || fail "a simplemap's poses differ from the run's"
import sys
a, b = ([[float(x) for x in l.split()] for l in open(p)] for p in sys.argv[1:])
sys.exit(0 if len(a) == len(b) == 24 and max(abs(x - y) for r, s in zip(a, b) for x, y in zip(r, s)) < 1e-6 else 1)
PY
grep -q "(MRPT simplemap)" <<<"$("$bin/cleanmap-info" "$scratch/out/static_map.simplemap")" || fail "cleanmap-info does not see a simplemap"
# DESIGN §2b: the auto window spans 1 s at the rate of the scans' timestamps, from times.txt and
# from the rawlog's observations alike (10 Hz: K 10).
window_of() {
  python3 -c 'import json,sys; w=json.load(open(sys.argv[1]))["window"]; print(w["k"], round(w["scan_rate_hz"], 3), w["window_k"])' "$1"
}
[[ $(window_of "$scratch/out/report.json") == "10 10.0 auto" ]] || fail "window: $(window_of "$scratch/out/report.json")"
"$bin/cleanmap" "$seq/sequence.rawlog" -o "$scratch/rawwin" --quiet --last 6 --no-mrpt-outputs >/dev/null 2>"$scratch/rawwin.err" ||
  fail "a rawlog run failed"
grep -q "sparser than" "$scratch/rawwin.err" && fail "scans at 10 Hz were called sparse"
# Every third scan (0.3 s apart, as a SLAM's keyframes may be) is said in one warning: the window
# compares neighbouring sweeps.
mkdir -p "$scratch/sparse/velodyne" && cp "$seq/calib.txt" "$scratch/sparse/"
for i in 0 3 6 9 12 15; do
  ln -s "$seq/velodyne/$(printf %06d $i).bin" "$scratch/sparse/velodyne/"
  sed -n "$((i + 1))p" "$seq/poses.txt" >>"$scratch/sparse/poses.txt"
  sed -n "$((i + 1))p" "$seq/times.txt" >>"$scratch/sparse/times.txt"
done
"$bin/cleanmap" "$scratch/sparse" -o "$scratch/sparse_out" --quiet --no-mrpt-outputs >/dev/null 2>"$scratch/sparse.err" ||
  fail "a run of sparse scans failed"
grep -q "warning: $scratch/sparse: the scans are 0.30 s and [0-9.]* m apart (median), sparser than a lidar's sweeps" "$scratch/sparse.err" ||
  fail "no warning for scans 0.3 s apart: $(cat "$scratch/sparse.err")"
spacing_of() {
  python3 -c 'import json,sys; s=json.load(open(sys.argv[1]))["window"]["scan_spacing"]; print(round(s["seconds"], 2), s["sparser_than_sweeps"])' "$1"
}
[[ $(spacing_of "$scratch/sparse_out/report.json") == "0.3 True" ]] || fail "report.json spacing: $(spacing_of "$scratch/sparse_out/report.json")"
[[ $(spacing_of "$scratch/rawwin/report.json") == "0.1 False" ]] || fail "report.json spacing at 10 Hz: $(spacing_of "$scratch/rawwin/report.json")"
grep -q "^spacing: the scans are 0.30 s and" <<<"$("$bin/cleanmap-info" "$scratch/sparse")" || fail "cleanmap-info does not say the scans are sparse"
grep -q "^spacing: 0.10 s and [0-9.]* m between scans (median)" <<<"$("$bin/cleanmap-info" "$seq")" || fail "cleanmap-info gives no spacing"
[[ $(window_of "$scratch/rawwin/report.json") == "10 10.0 auto" ]] || fail "rawlog window: $(window_of "$scratch/rawwin/report.json")"
sensors=$(python3 -c 'import json,sys; s=json.load(open(sys.argv[1]))["rawlog_sensors"]; print(s["lidar"], s["other_lidars"])' "$scratch/rawwin/report.json")
[[ $sensors == "LIDAR {}" ]] || fail "rawlog sensors: $sensors"
"$bin/cleanmap" "$seq" -o "$scratch/out" --quiet --last 4 >/dev/null || fail "second run failed"
[[ $(ls "$scratch/out/labels" | wc -l) -eq 5 ]] || fail "stale label files survived the shorter run"
[[ $(ls -A "$scratch" | grep -c cleanmap-staging) -eq 0 ]] || fail "a staging folder was left"
"$bin/cleanmap-eval" "$seq" "$scratch/out" --last 4 --json >/dev/null || fail "eval refused a finished run"

# One scan: nothing to compare it with; said in one warning, every point static (no 251).
"$bin/cleanmap" "$seq" -o "$scratch/one" --first 3 --last 3 --quiet >/dev/null 2>"$scratch/one.err" ||
  fail "a one-scan run failed"
grep -q "one scan: the moving test compares" "$scratch/one.err" || fail "a one-scan run gave no warning"
od -An -tu4 -v "$scratch/one/labels/000003.label" | grep -qw 251 && fail "a lone scan has moving points"

# A real signal in the middle of a run: exit 128 + signal, one line, staging removed, the earlier
# run untouched.
before=$(cat "$scratch/out/report.json")
for sig in INT TERM; do
  "$bin/cleanmap" "$seq" -o "$scratch/out" --quiet --threads 1 >/dev/null 2>"$scratch/err" &
  pid=$!
  for _ in $(seq 600); do  # wait until the run has written labels into its staging folder
    compgen -G "$scratch/.out.cleanmap-staging-$pid/labels/*.label" >/dev/null && break
    sleep 0.05
  done
  compgen -G "$scratch/.out.cleanmap-staging-$pid/labels/*.label" >/dev/null || fail "SIG$sig: no staging labels seen"
  kill -s "$sig" "$pid"
  wait "$pid"; rc=$?
  want=$([[ $sig == INT ]] && echo 130 || echo 143)
  [[ $rc -eq $want ]] || fail "SIG$sig: exit $rc, expected $want"
  [[ $(wc -l <"$scratch/err") -eq 1 ]] && grep -q "interrupted by SIG$sig" "$scratch/err" ||
    fail "SIG$sig: message '$(cat "$scratch/err")'"
  [[ -e $scratch/.out.cleanmap-staging-$pid ]] && fail "SIG$sig: staging folder left behind"
  [[ "$(cat "$scratch/out/report.json")" == "$before" ]] || fail "SIG$sig: the earlier run was touched"
  [[ $(ls "$scratch/out/labels" | wc -l) -eq 5 ]] || fail "SIG$sig: the earlier run's labels changed"
done
ls -A "$scratch" | grep -q '\.tmp\.' && fail "temporary files left beside the outputs"

# An error in the middle of a run (a truncated scan) also leaves the earlier run as it was.
cp -r "$seq" "$scratch/cut"; rm -f "$scratch/cut/sequence.rawlog"
truncate -s 1000 "$scratch/cut/velodyne/000006.bin"
expect_error 1 "000006.bin: truncated scan" "$bin/cleanmap" "$scratch/cut" -o "$scratch/out"
[[ "$(cat "$scratch/out/report.json")" == "$before" ]] || fail "a failed run touched the earlier run"
[[ $(ls -A "$scratch" | grep -c cleanmap-staging) -eq 0 ]] || fail "a failed run left its staging folder"

# A disk that fills up (full_disk: a file-size limit), early and in the last kilobyte of the run's
# largest file: one line, the earlier run as it was. The run is the earlier one's (--last 4), so its
# largest file is as large.
largest=$(find "$scratch/out" -type f -printf '%s\n' | sort -n | tail -1)
for kb in 64 $(((largest - 1) / 1024)); do
  expect_error 1 "write failed (disk full?)" full_disk "$kb" "$bin/cleanmap" "$seq" -o "$scratch/out" --quiet --last 4
  [[ "$(cat "$scratch/out/report.json")" == "$before" ]] || fail "full disk at $kb KB: the earlier run was touched"
  [[ $(ls -A "$scratch" | grep -c cleanmap-staging) -eq 0 ]] || fail "full disk at $kb KB: staging folder left"
done

# cleanmap-eval refuses a folder that is no finished run.
mkdir -p "$scratch/half/labels"; cp "$scratch/out/labels/000000.label" "$scratch/half/labels/"
expect_error 1 "not a finished cleanmap run" "$bin/cleanmap-eval" "$seq" "$scratch/half"

# A non-empty folder that is no cleanmap output is refused, or replaced with --force.
mkdir -p "$scratch/mine"; echo keep >"$scratch/mine/notes.txt"
expect_error 1 "holds no cleanmap run" "$bin/cleanmap" "$seq" -o "$scratch/mine" --last 2
[[ -f $scratch/mine/notes.txt ]] || fail "a refused folder was modified"
"$bin/cleanmap" "$seq" -o "$scratch/mine" --last 2 --force --quiet >/dev/null || fail "--force failed"
[[ ! -e $scratch/mine/notes.txt && -f $scratch/mine/report.json ]] || fail "--force did not replace the folder"
# --force never takes the input with it: not a folder that holds it (here through a link to it),
# not a non-empty folder inside it. An output folder inside it is fine.
mkdir -p "$scratch/holder" && ln -s "$seq" "$scratch/holder/seq"
expect_error 1 "holds the input" "$bin/cleanmap" "$scratch/holder/seq" -o "$scratch/holder" --force --last 2
expect_error 1 "lies inside the input folder" "$bin/cleanmap" "$seq" -o "$seq/velodyne" --force --last 2
[[ -L $scratch/holder/seq && $(ls "$seq/velodyne" | wc -l) -eq 24 ]] || fail "a refused run touched its input"
# A rawlog's external files are input too: a rawlog that references the sequence's .bin files
# (--external) cannot be cleaned into the sequence's folder or its velodyne/, --force or not.
"$bin/cleanmap-kitti2rawlog" "$seq" "$scratch/ext.rawlog" --external >/dev/null || fail "kitti2rawlog --external failed"
expect_error 1 "holds the input $seq/velodyne" "$bin/cleanmap" "$scratch/ext.rawlog" -o "$seq" --force --last 2
expect_error 1 "the output folder is the input folder" "$bin/cleanmap" "$scratch/ext.rawlog" -o "$seq/velodyne" --force --last 2
expect_error 1 "holds the input $seq/velodyne" "$bin/cleanmap-build-map" "$scratch/ext.rawlog" -c "$(dirname "$0")/../../config/cleanmap.ini" -o "$seq" --force
[[ $(ls "$seq/velodyne" | wc -l) -eq 24 ]] || fail "a refused run touched the files its rawlog references"
# MRPT's own externalized rawlog (rawlog-edit --externalize: files named relative to the rawlog, in
# <name>_Images beside it) reads as the embedded one, from any working folder.
if command -v rawlog-edit >/dev/null; then
  rawlog-edit --externalize -i "$seq/sequence.rawlog" -o "$scratch/mrptext.rawlog" >/dev/null 2>&1 || fail "rawlog-edit --externalize failed"
  [[ -d $scratch/mrptext_Images ]] || fail "rawlog-edit wrote no mrptext_Images/"
  (cd / && "$bin/cleanmap" "$scratch/mrptext.rawlog" -o "$scratch/mrptext_out" --quiet --last 3 --no-mrpt-outputs >/dev/null) || fail "an externalized rawlog did not run"
  "$bin/cleanmap" "$seq/sequence.rawlog" -o "$scratch/embedded_out" --quiet --last 3 --no-mrpt-outputs >/dev/null || fail "the embedded rawlog did not run"
  diff -r "$scratch/mrptext_out/labels" "$scratch/embedded_out/labels" >/dev/null || fail "externalized and embedded rawlogs gave different labels"
  expect_error 1 "the output folder is the input folder" "$bin/cleanmap" "$scratch/mrptext.rawlog" -o "$scratch/mrptext_Images" --force --last 2
fi
"$bin/cleanmap" "$seq" -o "$seq/cleaned" --last 2 --quiet >/dev/null || fail "a run into the input's own subfolder failed"
rm -rf "$seq/cleaned"

# Empty scans: one rule in every app. A 0-byte scan (and its 0-entry label file) and an all-NaN
# scan are kept, counted, labelled 0 per original point.
cp -r "$seq" "$scratch/holes"; rm -f "$scratch/holes/sequence.rawlog"
: >"$scratch/holes/velodyne/000003.bin"; : >"$scratch/holes/labels/000003.label"
python3 - "$scratch/holes/velodyne/000005.bin" <<'PY'
import struct, sys
n = len(open(sys.argv[1], 'rb').read()) // 16
open(sys.argv[1], 'wb').write(struct.pack('<f', float('nan')) * 4 * n)
PY
npts=$(( $(stat -c %s "$scratch/holes/velodyne/000005.bin") / 16 ))
"$bin/cleanmap" "$scratch/holes" -o "$scratch/holes_out" --quiet --last 6 >"$scratch/o" 2>"$scratch/e" || fail "empty scans stopped cleanmap"
grep -q "warning: 2 empty scans" "$scratch/e" || fail "no empty-scan warning: $(cat "$scratch/e")"
grep -q '"empty_scans": 2' "$scratch/holes_out/report.json" || fail "report.json does not count 2 empty scans"
[[ $(stat -c %s "$scratch/holes_out/labels/000003.label") -eq 0 ]] || fail "0-byte scan: label file not empty"
[[ $(stat -c %s "$scratch/holes_out/labels/000005.label") -eq $((4 * npts)) ]] || fail "all-NaN scan: wrong label count"
[[ -z $(tr -d '\0' <"$scratch/holes_out/labels/000005.label") ]] || fail "all-NaN scan: labels not all 0"
grep -q "2 empty scans" <<<"$("$bin/cleanmap-info" "$scratch/holes")" || fail "cleanmap-info does not count them"
out=$("$bin/cleanmap-kitti2rawlog" "$scratch/holes" "$scratch/holes.rawlog") || fail "kitti2rawlog refused empty scans"
[[ $out == *"2 empty scans kept"* ]] || fail "kitti2rawlog: $out"
"$bin/cleanmap" "$scratch/holes.rawlog" -o "$scratch/holes_rl" --quiet --last 6 >/dev/null 2>&1 || fail "empty scans stopped cleanmap on a rawlog"
"$bin/cleanmap-eval" "$scratch/holes" "$scratch/holes_out" --last 6 --json >/dev/null || fail "cleanmap-eval failed on empty scans"

# A rawlog whose scans go back in time (here the sequence joined to itself) is read in file order,
# with one warning line, counted in report.json; cleanmap-info says so too.
(gzip -dc "$seq/sequence.rawlog"; gzip -dc "$seq/sequence.rawlog") | gzip -1 >"$scratch/twice.rawlog"
"$bin/cleanmap" "$scratch/twice.rawlog" -o "$scratch/twice" --quiet --first 20 --last 27 --no-mrpt-outputs >/dev/null 2>"$scratch/e" ||
  fail "a rawlog timed back stopped cleanmap: $(cat "$scratch/e")"
grep -q "warning: 1 scan is timed earlier than the scan before (the first: .*twice.rawlog entry .*, 2.300 s before" "$scratch/e" ||
  fail "no warning for the scans timed back: $(cat "$scratch/e")"
[[ $(ls "$scratch/twice/labels" | wc -l) -eq 8 ]] || fail "a rawlog timed back: expected 8 label files"
grep -q '"scans_timed_back": 1' "$scratch/twice/report.json" || fail "report.json does not count the scan timed back"
grep -q '"scans_timed_back": 0' "$scratch/rawwin/report.json" || fail "report.json counts scans timed back in an ordered rawlog"
grep -q "^times: *1 scan is timed earlier" <<<"$("$bin/cleanmap-info" "$scratch/twice.rawlog")" || fail "cleanmap-info does not say the scans go back"

# Bad inputs: one line naming what is wrong.
expect_error 1 "--first 40 is beyond the end: the input has 24 scans (0..23)" "$bin/cleanmap" "$seq" -o "$scratch/x" --first 40
head -c 20000 /dev/urandom >"$scratch/random.rawlog"
expect_error 1 "random.rawlog: is not an MRPT rawlog" "$bin/cleanmap" "$scratch/random.rawlog" -o "$scratch/x"
expect_error 1 "random.rawlog: is not an MRPT rawlog" "$bin/cleanmap-info" "$scratch/random.rawlog"
cp -r "$seq" "$scratch/noposes"; rm "$scratch/noposes/poses.txt" "$scratch/noposes/sequence.rawlog"
expect_error 1 "velodyne/000000.bin: has no pose" "$bin/cleanmap" "$scratch/noposes" -o "$scratch/x" --poses given
"$bin/cleanmap-kitti2rawlog" "$scratch/noposes" "$scratch/noposes.rawlog" >/dev/null || fail "conversion failed"
expect_error 1 "noposes.rawlog entry 0: has no pose" "$bin/cleanmap" "$scratch/noposes.rawlog" -o "$scratch/x" --poses given
expect_error 1 "has no pose to refine" "$bin/cleanmap" "$scratch/noposes.rawlog" -o "$scratch/x" --poses refine
# One lidar per run (doc/MRPT.md): a label the rawlog lacks, or a label for a KITTI folder.
expect_error 1 "noposes.rawlog: holds no scans of lidar 'FRONT'; its lidars: 'LIDAR' (24)" "$bin/cleanmap" "$scratch/noposes.rawlog" -o "$scratch/x" --lidar FRONT
expect_error 1 "is a KITTI folder: a lidar or camera label selects the sensors of a rawlog" "$bin/cleanmap" "$seq" -o "$scratch/x" --lidar LIDAR
[[ -e $scratch/x ]] && fail "a failed run created its output folder"
expect_error 2 "--poses is given, gicp or refine" "$bin/cleanmap" "$seq" -o "$scratch/x" --poses odometry

# Without poses, the run estimates them (GICP odometry, DESIGN §2.1) and says so per scan.
"$bin/cleanmap" "$scratch/noposes" -o "$scratch/gicp" --last 5 >/dev/null 2>"$scratch/gicp.err" || fail "an unposed input did not run"
grep -q '"source": "gicp"' "$scratch/gicp/report.json" || fail "report.json does not say the poses came from gicp"
[[ $(wc -l <"$scratch/gicp/poses_tum.txt") -eq 6 ]] || fail "poses_tum.txt does not hold 6 poses"
grep -q "GICP refused" "$scratch/gicp.err" && fail "a street GICP tracks got a refusal warning: $(cat "$scratch/gicp.err")"
grep -q "^6 of 6 scans aligned or first" "$scratch/gicp/report.md" || fail "report.md: no registration summary"
# The road alone (its points below 1.5 m under the sensor): nothing holds the step along it, every
# alignment is refused as degenerate, and the run says so in one line and in report.md.
cp -r "$scratch/noposes" "$scratch/road"; rm -rf "$scratch/road/labels"
python3 - "$scratch/road/velodyne" <<'PY'
import os, struct, sys
for f in sorted(os.listdir(sys.argv[1]))[:6]:
    path = os.path.join(sys.argv[1], f)
    b = open(path, 'rb').read()
    p = struct.unpack('<%df' % (len(b) // 4), b)
    road = [p[i:i + 4] for i in range(0, len(p), 4) if p[i + 2] < -1.5]
    open(path, 'wb').write(b''.join(struct.pack('<4f', *q) for q in road))
PY
"$bin/cleanmap" "$scratch/road" -o "$scratch/road_out" --last 5 --quiet >/dev/null 2>"$scratch/road.err" || fail "the road alone did not run"
grep -q "warning: GICP refused the alignment of 5 of 6 scans (degenerate scene: 5); their poses are the guess, the motion model's or the input odometry's" "$scratch/road.err" ||
  fail "no warning for refused alignments: $(cat "$scratch/road.err")"
grep -q "| degenerate scene | 5 |" "$scratch/road_out/report.md" || fail "report.md does not count the refused alignments"
# MRPT's own one-scan VLP-16 rawlog (no pose): a window of one.
vlp=/usr/share/mrpt/datasets/test_velodyne_VLP16.rawlog
if [[ -f $vlp ]]; then
  "$bin/cleanmap" "$vlp" -o "$scratch/vlp" >/dev/null || fail "the one-scan VLP-16 rawlog did not run"
  [[ -f $scratch/vlp/labels/000000.label ]] || fail "no labels for the VLP-16 scan"
  # Its packets time every firing (DESIGN §2.0): a sweep of about 0.1 s.
  "$bin/cleanmap-info" "$vlp" | grep -qE "^point times: 1 of 1 scans, sweep (9[0-9]|10[0-9])\.[0-9] ms" ||
    fail "cleanmap-info does not see the VLP-16 firing times: $("$bin/cleanmap-info" "$vlp" | grep 'point times')"
  # Its columns are 0.4 degrees apart (0.007 rad): the free-space walk's bins follow (DESIGN §2e).
  azbin=$(grep -A2 '"free_space_azimuth_bin_rad"' "$scratch/vlp/report.json" | grep -o '"min": [0-9.e-]*' | cut -d' ' -f2)
  awk -v b="$azbin" 'BEGIN { exit !(b > 0.0068 && b < 0.0085) }' || fail "VLP-16 free-space azimuth bin '$azbin', expected its 0.007 rad step"
fi
# MRPT's rotating-scan rawlog (CObservationRotatingScan), and the MRPT outputs as MRPT's own tool
# reads them: the cleaned rawlog holds one LIDAR and one POSE observation, stamped after 1970.
rot=/usr/share/mrpt/datasets/rot_scan_velodyne.rawlog
if [[ -f $rot ]]; then
  "$bin/cleanmap" "$rot" -o "$scratch/rot" >/dev/null || fail "the rotating-scan rawlog did not run"
  for f in static_map.3Dscene static_map.simplemap cleaned.rawlog labelled.rawlog static_map.pcd dynamic.pcd; do
    [[ -s $scratch/rot/$f ]] || fail "no $f"
  done
  if command -v rawlog-edit >/dev/null; then
    info=$(rawlog-edit --info -i "$scratch/rot/cleaned.rawlog" 2>&1)
    grep -qE "LIDAR +/ +1 " <<<"$info" && grep -qE "POSE +/ +1 " <<<"$info" ||
      fail "rawlog-edit does not see one LIDAR and one POSE in cleaned.rawlog"
    grep -q "Earliest timestamp *: 1[0-9]\{9\}" <<<"$info" || fail "cleaned.rawlog: timestamp not a real time"
  fi
fi
"$bin/cleanmap" "$seq" -o "$scratch/nomrpt" --last 3 --no-mrpt-outputs >/dev/null 2>"$scratch/nomrpt.err" || fail "--no-mrpt-outputs run failed"
# DESIGN §2e: the free-space map grows with the ground covered; past half the memory (here set
# to 1 MiB) one warning says so, with what to do, and the run goes on. None at this machine's.
grep -q "free-space map holds" "$scratch/nomrpt.err" && fail "a memory warning on a short run: $(cat "$scratch/nomrpt.err")"
CLEANMAP_MEMORY_MIB=1 "$bin/cleanmap" "$seq" -o "$scratch/mem" --last 3 --no-mrpt-outputs >/dev/null 2>"$scratch/mem.err" || fail "a run past half the memory failed"
[[ $(grep -c "warning: the free-space map holds [0-9]* MiB after [0-9]* scans\?, over half of the 1 MiB of memory here; .* (static_map.clean = 0)$" "$scratch/mem.err") -eq 1 ]] ||
  fail "not one memory warning: $(cat "$scratch/mem.err")"
[[ -s $scratch/mem/static_map_full.ply ]] || fail "the run past the memory warning wrote no map"
CLEANMAP_MEMORY_MIB=lots expect_error 1 "CLEANMAP_MEMORY_MIB: is 'lots': give the memory in MiB" "$bin/cleanmap" "$seq" -o "$scratch/x" --last 3
[[ -e $scratch/nomrpt/cleaned.rawlog || -e $scratch/nomrpt/static_map.3Dscene ]] && fail "--no-mrpt-outputs wrote MRPT outputs"
expect_error 2 "viewer-voxel" "$bin/cleanmap" "$seq" -o "$scratch/x" --viewer-voxel 0
expect_error 2 "unknown option" "$bin/cleanmap" "$seq" -o "$scratch/x" --bogus

# The maps come from an MRPT ini through CMultiMetricMap (DESIGN §4b): config/cleanmap.ini gives
# the same labels as the built-in defaults and a ground model; a run's flat params.ini is
# accepted; MRPT's silent ignores are errors here.
ini=$(dirname "$0")/../../config/cleanmap.ini
"$bin/cleanmap" "$seq" -o "$scratch/ini" --quiet --last 6 -c "$ini" >/dev/null || fail "run with config/cleanmap.ini failed"
"$bin/cleanmap" "$seq" -o "$scratch/noini" --quiet --last 6 >/dev/null || fail "run without -c failed"
diff -rq "$scratch/ini/labels" "$scratch/noini/labels" >/dev/null || fail "config/cleanmap.ini labels differ from the defaults"
[[ -s $scratch/ini/ground_model.ply && -s $scratch/ini/ground_model.txt ]] || fail "no ground model written"
# With two threads the ground model is saved beside the map's decision, with one after it; and a
# finished run ends without its destructors: what it printed, through a pipe, is all there.
out=$("$bin/cleanmap" "$seq" -o "$scratch/ini1" --quiet --last 6 -c "$ini" --threads 1) ||
  fail "run with --threads 1 failed"
grep -q "cleanmap: 7 scans in .*; results in $scratch/ini1" <<<"$out" || fail "the run's summary line is missing: $out"
# The line and report.json `process` say the whole command: the scans, the start-up before them
# and the map's final decision after them add up to it, and its CPU is that of a run.
grep -q "cleanmap: 7 scans in [0-9.]* s, [0-9.]* s in all (start-up [0-9.]* s, the map's final decision and files [0-9.]* s)" <<<"$out" ||
  fail "the summary line does not say the whole run's time: $out"
python3 - "$scratch/ini1/report.json" <<'PY' || fail "report.json process does not add up"
import json, sys
r = json.load(open(sys.argv[1]))
p = r["process"]
assert p["start_s"] > 0 and p["end_s"] > 0 and p["cpu_s"] > 0, p
assert abs(p["start_s"] + r["wall_s"] + p["end_s"] - p["wall_s"]) < 1e-6, (p, r["wall_s"])
assert p["wall_s"] < 600, p
PY
"$bin/cleanmap" "$seq" -o "$scratch/ini2" --quiet --last 6 -c "$ini" --threads 2 >/dev/null ||
  fail "run with --threads 2 failed"
for f in ground_model.ply ground_model.txt; do
  cmp -s "$scratch/ini1/$f" "$scratch/ini2/$f" || fail "$f differs between one and two threads"
done
"$bin/cleanmap" "$seq" -o "$scratch/flat" --quiet --last 6 -c "$scratch/ini/params.ini" >/dev/null || fail "a run's params.ini was refused"
diff -rq "$scratch/ini/labels" "$scratch/flat/labels" >/dev/null || fail "params.ini labels differ"
sed 's/^cleanmap_moving_count/cleanmap_movin_count/' "$ini" >"$scratch/typo.ini"
expect_error 1 "typo.ini: [MappingApplication]: unknown map 'cleanmap_movin'" "$bin/cleanmap" "$seq" -o "$scratch/t" -c "$scratch/typo.ini"
sed 's/^ds.window_k = auto/ds.windw_k = auto/' "$ini" >"$scratch/key.ini"
expect_error 1 "unknown key 'ds.windw_k'; did you mean 'ds.window_k'?" "$bin/cleanmap" "$seq" -o "$scratch/t" -c "$scratch/key.ini"
sed 's/^height = auto/height = 1.9/' "$ini" >"$scratch/ground.ini"
expect_error 1 "the cleanmap_ground map's height (1.9) differs from cleanmap_moving's sensor.height (auto)" "$bin/cleanmap" "$seq" -o "$scratch/t" -c "$scratch/ground.ini"
# Issue #15: the old key names its replacement; a mounting height the scans contradict is warned.
printf '[ground]\nsensor_height = -1.73\n' >"$scratch/old.ini"
expect_error 1 "old.ini:2: 'sensor_height' in [ground] is now [sensor] height" "$bin/cleanmap" "$seq" -o "$scratch/t" -c "$scratch/old.ini"
sed 's/^height = auto.*/sensor_height = -1.73/' "$ini" >"$scratch/old_mrpt.ini"
expect_error 1 "'sensor_height' is now 'height'" "$bin/cleanmap" "$seq" -o "$scratch/t" -c "$scratch/old_mrpt.ini"
printf '[sensor]\nheight = 0.8\n' >"$scratch/low.ini"
"$bin/cleanmap" "$seq" -o "$scratch/low" --quiet --last 6 --no-mrpt-outputs -c "$scratch/low.ini" 2>"$scratch/low.err" >/dev/null || fail "a run with [sensor] height = 0.8 failed"
grep -q "warning: .*low.ini: \[sensor\] height = 0.8 m, but the ground measured in the scans lies 1.[6-9][0-9] m below the sensor" "$scratch/low.err" || fail "no warning for a wrong sensor height: $(cat "$scratch/low.err")"
[[ -e $scratch/t ]] && fail "a refused configuration produced an output folder"
# DESIGN §3, the camera check: --images on needs images; with them, overlays and the report.
expect_error 1 "--images on, but the input has no camera calibration" "$bin/cleanmap" "$seq" -o "$scratch/t" --images on
expect_error 2 "--images is on, off or auto" "$bin/cleanmap" "$seq" -o "$scratch/t" --images yes
"$bin/cleanmap-sim" -o "$scratch/cam" --frames 8 --threads 2 >/dev/null 2>&1 || fail "sim with images failed"
"$bin/cleanmap" "$scratch/cam" -o "$scratch/cam_out" --quiet --images on --save-overlays --no-mrpt-outputs >/dev/null ||
  fail "run with images failed"
[[ $(ls "$scratch/cam_out/overlays" 2>/dev/null | grep -c '\.png$') -eq 8 ]] || fail "expected 8 overlay images"
grep -q '"scans_with_image": 8' "$scratch/cam_out/report.json" || fail "report.json: images.scans_with_image is not 8"
"$bin/cleanmap" "$scratch/cam" -o "$scratch/cam_off" --quiet --images off --no-mrpt-outputs --last 3 >/dev/null || fail "--images off failed"
grep -q '"scans_with_image": 0' "$scratch/cam_off/report.json" || fail "--images off still used the images"
expect_error 1 "--images on, but no scan came with a camera image" "$bin/cleanmap" "$seq/sequence.rawlog" -o "$scratch/t" --images on --no-mrpt-outputs --last 3
"$bin/cleanmap" "$scratch/cam/sequence.rawlog" -o "$scratch/cam_rl_out" --quiet --images on --save-overlays --no-mrpt-outputs --last 3 >/dev/null ||
  fail "rawlog run with images failed"
[[ $(ls "$scratch/cam_rl_out/overlays" 2>/dev/null | grep -c '\.png$') -eq 4 ]] || fail "rawlog: expected 4 overlay images"

sed 's/^static_map.policy = transient/static_map.policy = transiant/' "$ini" >"$scratch/policy.ini"
expect_error 1 "'static_map.policy' needs one of moving, transient; got 'transiant'" "$bin/cleanmap" "$seq" -o "$scratch/t" -c "$scratch/policy.ini"

# DESIGN §2e: the map's own decisions per point, and the cleaning removes moving points the
# windowed test kept (the default scenario's movers) without costing the static map much.
[[ $(ls "$scratch/ini/map_labels" | wc -l) -eq 7 && -s $scratch/ini/map_removed.ply ]] || fail "no map_labels/ or map_removed.ply"
sed 's/^clean = 1/clean = 0/' "$scratch/ini/params.ini" >"$scratch/noclean.ini"
"$bin/cleanmap" "$seq" -o "$scratch/noclean" --quiet -c "$scratch/noclean.ini" >/dev/null || fail "run without cleaning failed"
"$bin/cleanmap-eval" "$seq" "$scratch/noclean" --json >"$scratch/noclean.json" || fail "eval of the run without cleaning failed"
"$bin/cleanmap-eval" "$seq" "$scratch/clean" --json >"$scratch/clean.json" || fail "eval of the run with cleaning failed"
score() { sed -n "s/^ *\"$2\": \([0-9.e-]*\),*$/\1/p" "$scratch/$1.json"; }
da0=$(score noclean DA) da1=$(score clean DA) sa0=$(score noclean SA) sa1=$(score clean SA)
echo "cleanmap_test: map DA $da0 -> $da1, SA $sa0 -> $sa1 with the free-space cleaning"
awk -v a="$da0" -v b="$da1" 'BEGIN { exit !(b >= a) }' || fail "cleaning lowered DA ($da0 -> $da1)"
awk -v a="$sa0" -v b="$sa1" 'BEGIN { exit !(b >= a - 0.03) }' || fail "cleaning cost more than 0.03 SA ($sa0 -> $sa1)"

# The `cleanmap` launcher (issue #16): it hands the run to cleanmap-run with glibc's huge-page
# tunable set (unless CLEANMAP_HUGEPAGES=0), and names the app it cannot find in one line.
if [[ -e /sys/kernel/mm/transparent_hugepage/enabled ]] &&
  ! grep -q '\[never\]' /sys/kernel/mm/transparent_hugepage/enabled; then
  "$bin/cleanmap" "$seq" -o "$scratch/tun" --quiet --threads 1 --last 5 >/dev/null 2>&1 &
  pid=$!
  for _ in $(seq 200); do
    env_=$(tr '\0' '\n' <"/proc/$pid/environ" 2>/dev/null) && [[ $env_ == *GLIBC_TUNABLES* ]] && break
    sleep 0.02
  done
  grep -q 'glibc.malloc.hugetlb=1' <<<"$env_" || fail "the launcher did not set the huge-page tunable"
  wait "$pid" || fail "the run through the launcher failed"
fi
mkdir -p "$scratch/alone" && cp "$bin/cleanmap" "$scratch/alone/"
"$scratch/alone/cleanmap" --help >/dev/null 2>"$scratch/err"; rc=$?
[[ $rc -eq 127 && $(wc -l <"$scratch/err") -eq 1 ]] && grep -q "cannot run $scratch/alone/cleanmap-run" "$scratch/err" ||
  fail "launcher without its app: exit $rc, message '$(cat "$scratch/err")'"

[[ $fails -eq 0 ]] && echo "cleanmap_test: all checks passed"
finish

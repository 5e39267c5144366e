#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# `make fuzz`: runs every libFuzzer target of tests/fuzz (built in BUILD with CLEANMAP_FUZZ=ON)
# for SECONDS each, seeded with the committed corpus. New interesting inputs go to
# BUILD/fuzz-work/<target>/corpus (not committed); a crash, leak, timeout or allocation over the
# limit leaves its input in BUILD/fuzz-work/<target>/findings/ and fails the run. A finding, once
# fixed, goes into tests/fuzz/corpus/<target>/ so that `make test` replays it for good.
set -euo pipefail
BUILD=${1:-build-fuzz}
SECONDS_EACH=${2:-60}
shift 2 || true
SRC=$(cd "$(dirname "$0")/.." && pwd)
TARGETS=("$@")
if [[ ${#TARGETS[@]} -eq 0 ]]; then
  mapfile -t TARGETS < <(ls "$SRC/tests/fuzz/corpus")
fi
failed=()
for t in "${TARGETS[@]}"; do
  exe="$BUILD/tests/fuzz/fuzz_$t"
  [[ -x "$exe" ]] || { echo "fuzz: no target $exe (make fuzz builds them)" >&2; exit 2; }
  work="$BUILD/fuzz-work/$t"
  mkdir -p "$work/corpus" "$work/findings"
  echo "fuzz: $t for ${SECONDS_EACH}s"
  # -malloc_limit_mb: one allocation above it is a finding (absurd headers must not allocate).
  opts=(-max_total_time="$SECONDS_EACH" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024
        -max_len=65536 -print_final_stats=1 -artifact_prefix="$work/findings/")
  seeds=("$SRC/tests/fuzz/corpus/$t")
  # A target's dictionary, where it has one (rawlog: every MRPT class's object header).
  if [[ -f "$SRC/tests/fuzz/$t.dict" ]]; then opts+=(-dict="$SRC/tests/fuzz/$t.dict"); fi
  if [[ "$t" == rawlog ]]; then
    # MRPT's sample rawlogs, where installed: rotating scans and Velodyne packets to start from.
    mkdir -p "$work/mrpt-seeds"
    for f in rot_scan_2d rot_scan_velodyne test_velodyne_VLP16; do
      if [[ -f /usr/share/mrpt/datasets/$f.rawlog ]]; then
        cp "/usr/share/mrpt/datasets/$f.rawlog" "$work/mrpt-seeds/"
      fi
    done
    seeds+=("$work/mrpt-seeds")
    # MRPT's own deserializers allocate what a length field claims before reading it (a points
    # map: 4 arrays of up to 2^32 floats) and decode JPEG images with libjpeg's exit-on-error
    # handler (doc/FUZZING.md). Fork mode keeps fuzzing past those; each saved input is then
    # replayed and counted as upstream only if it is one of them.
    opts+=(-fork=1 -ignore_ooms=1 -ignore_crashes=1 -ignore_timeouts=0)
  fi
  if ! TMPDIR="$work" "$exe" "${opts[@]}" "$work/corpus" "${seeds[@]}" \
      > "$work/log.txt" 2>&1 && [[ "$t" != rawlog ]]; then  # rawlog: judged per input below
    failed+=("$t")
    tail -n 30 "$work/log.txt" >&2
  fi
  if [[ "$t" == rawlog ]]; then
    upstream=0
    for f in "$work"/findings/*; do
      [[ -f "$f" ]] || continue
      # The slow unwinder: MRPT's frames (Debian's build keeps no frame pointers) in the stacks.
      replay() { ASAN_OPTIONS=fast_unwind_on_malloc=0 TMPDIR="$work" "$exe" "$@" "$f" 2>&1 || true; }
      mrpt_heap() {
        grep -A12 "Live Heap Allocations" <<<"$out" | grep -qE "serializeFrom|mrpt::serialization::"
      }
      # One allocation too large: over libFuzzer's limit, ASan's, or the memory there is.
      one_alloc="out-of-memory \(malloc\(|requested allocation size|allocator is out of memory"
      # The reader checks these classes' counts and sizes (doc/FUZZING.md): memory sized by one
      # of theirs (the nearest deserializer in the allocating stack, no string read between: MRPT's
      # string reader allocates the length it reads, and an observation's frame can be missing)
      # is ours, not upstream.
      checked="(CSensoryFrame|CSimpleMap|CActionCollection|CSimplePointsMap|CPointsMapXYZI|CImage"
      checked+="|CPointsMapXYZIRT|CColouredPointsMap)::serializeFrom"
      ours() {
        local stack
        stack=$({ grep -A14 -E "HandleMalloc|$one_alloc" <<<"$out"
                  grep -A12 "Live Heap Allocations" <<<"$out"; } | sed '/::serializeFrom/q')
        grep -qE "$checked" <<<"$(tail -n1 <<<"$stack")" && ! grep -q "basic_string<char" <<<"$stack"
      }
      out=$(replay -malloc_limit_mb=1024 -rss_limit_mb=2048)
      if grep -q "out-of-memory (used:" <<<"$out" && ! mrpt_heap; then  # find the allocation
        out=$(replay -malloc_limit_mb=100 -rss_limit_mb=8000)
      fi
      # Upstream: the JPEG exit, or an allocation made by MRPT's deserialization (an object's
      # serializeFrom, or the length of a class name read by CArchive): one allocation over the
      # limit, or the heap grown past the RSS limit where most of it was allocated (a std::deque
      # sized to a count read, block by block: "Live Heap Allocations", its largest context).
      if grep -q "corrupt rawlog entry: MRPT's decoder ended the process" <<<"$out" ||
         { grep -qE "$one_alloc" <<<"$out" &&
           grep -A14 -E "HandleMalloc|$one_alloc" <<<"$out" |
             grep -qE "serializeFrom|mrpt::serialization::"; } ||
         { grep -q "out-of-memory (used:" <<<"$out" && mrpt_heap; }; then
        if ours; then
          echo "fuzz: rawlog finding $f: memory sized by a count the reader checks:" >&2
          tail -n 20 <<<"$out" >&2
          [[ " ${failed[*]} " == *" rawlog "* ]] || failed+=("rawlog")
          continue
        fi
        upstream=$((upstream + 1))
        mkdir -p "$work/upstream" && mv "$f" "$work/upstream/"
      else
        echo "fuzz: rawlog finding $f:" >&2
        tail -n 20 <<<"$out" >&2
        [[ " ${failed[*]} " == *" rawlog "* ]] || failed+=("rawlog")
      fi
    done
    echo "fuzz: rawlog: $upstream inputs hit MRPT's own limits (kept in $work/upstream/)"
  fi
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$work/log.txt" | tr '\n' ' ' || true
  echo
done
if [[ ${#failed[@]} -gt 0 ]]; then
  echo "fuzz: FINDINGS in ${failed[*]}: inputs under $BUILD/fuzz-work/<target>/findings/" >&2
  exit 1
fi
echo "fuzz: ${#TARGETS[@]} targets, ${SECONDS_EACH}s each, no finding"

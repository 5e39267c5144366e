#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Keeps every K-th ring of a KITTI odometry folder (scans and labels), for testing cleanmap on
sparser lidars with real scans (issue #15: "the labelled sets decimated to 16 rings", K = 4).

KITTI .bin files store no ring number. The HDL-64E's points are stored ring after ring, each ring a
full turn starting at the scan's first azimuth th0, turning towards increasing azimuth; so a
point's ring is the number of whole turns between th0 and its unwrapped azimuth (the azimuth
jumps by -2 pi once per turn). Checked on the three labelled sets: 64 rings in every scan.

usage: decimate_kitti_rings.py SRC DST [K [OFFSET]] [--columns C]   (poses, calib, times,
objects.json are copied; rings OFFSET, OFFSET + K, ... are kept, OFFSET 0 by default: another
OFFSET gives another sparse lidar of the same scene; --columns C keeps, of every ring, the returns
whose azimuth lies in every C-th step of the HDL-64E's (360 / 2083 degrees): C = 2 gives columns
0.35 degrees apart, an Ouster's at 1024 columns)
Standard library only; about a minute per 30 scans.
"""
import math
import os
import shutil
import struct
import sys


HDL64_STEP = 2 * math.pi / 2083  # rad between the HDL-64E's columns at 10 Hz


def main():
    args = sys.argv[1:]
    columns = 1
    if "--columns" in args:
        i = args.index("--columns")
        if i + 1 >= len(args) or not args[i + 1].isdigit() or int(args[i + 1]) < 1:
            sys.exit("--columns needs a whole number C >= 1")
        columns = int(args[i + 1])
        del args[i:i + 2]
    if len(args) not in (2, 3, 4):
        sys.exit(__doc__)
    src, dst = args[0], args[1]
    keep = int(args[2]) if len(args) >= 3 else 4
    offset = int(args[3]) if len(args) == 4 else 0
    if keep < 1 or not 0 <= offset < keep:
        sys.exit(f"K must be >= 1 and 0 <= OFFSET < K (got K {keep}, OFFSET {offset})")
    velo = os.path.join(src, "velodyne")
    if not os.path.isdir(velo):
        sys.exit(f"{src}: not a KITTI odometry folder (no velodyne/)")
    os.makedirs(os.path.join(dst, "velodyne"), exist_ok=True)
    has_labels = os.path.isdir(os.path.join(src, "labels"))
    if has_labels:
        os.makedirs(os.path.join(dst, "labels"), exist_ok=True)
    for f in ("poses.txt", "calib.txt", "times.txt", "objects.json"):
        if os.path.exists(os.path.join(src, f)):
            shutil.copy(os.path.join(src, f), os.path.join(dst, f))
    rings = []
    for name in sorted(os.listdir(velo)):
        if not name.endswith(".bin"):
            continue
        data = open(os.path.join(velo, name), "rb").read()
        if len(data) % 16:
            sys.exit(f"{os.path.join(velo, name)}: truncated scan ({len(data)} bytes)")
        n = len(data) // 16
        label_path = os.path.join(src, "labels", name[:-4] + ".label")
        labels = open(label_path, "rb").read() if has_labels else b""
        if has_labels and len(labels) != 4 * n:
            sys.exit(f"{label_path}: {len(labels) // 4} labels for {n} points")
        pts = struct.unpack(f"<{4 * n}f", data)
        th0 = math.atan2(pts[1], pts[0]) if n else 0.0
        prev, turns, top = th0, 0, 0
        out, out_labels = bytearray(), bytearray()
        for i in range(n):
            a = math.atan2(pts[4 * i + 1], pts[4 * i])
            if a - prev < -math.pi:
                turns += 1
            prev = a
            ring = int(math.floor((a + 2 * math.pi * turns - th0) / (2 * math.pi) + 1e-9))
            top = max(top, ring)
            column = int(math.floor((a + math.pi) / HDL64_STEP))
            if ring % keep == offset and column % columns == 0:
                out += data[16 * i:16 * i + 16]
                if has_labels:
                    out_labels += labels[4 * i:4 * i + 4]
        rings.append(top + 1)
        with open(os.path.join(dst, "velodyne", name), "wb") as o:
            o.write(out)
        if has_labels:
            with open(os.path.join(dst, "labels", name[:-4] + ".label"), "wb") as o:
                o.write(out_labels)
    print(f"{src}: {len(rings)} scans, rings per scan {min(rings)}-{max(rings)}, kept every {keep}"
          f" from ring {offset}" + (f", every {columns} columns" if columns > 1 else ""))


if __name__ == "__main__":
    main()

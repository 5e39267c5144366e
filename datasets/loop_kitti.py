#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Makes a long KITTI folder out of a short one, for steady-state timing (issue #16, doc/BENCHMARK.md).

The sequence is driven forth and back: scans 0..n-1, n-2..1, 0..n-1, ... so that consecutive
scans are always neighbours with their own poses (a drive played backwards is a drive too: the
movers move backwards, the static world stays where it is). Scans, labels and images are symbolic
links to SRC (KITTI data must not be copied into the project: write DST outside it); poses.txt,
times.txt (the source's mean period) and calib.txt are written.

usage: loop_kitti.py SRC DST --scans N
"""
import argparse
import os
import sys


def fail(msg):
    sys.exit(f"loop_kitti.py: {msg}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--scans", type=int, required=True, help="scans in DST (>= 1)")
    a = ap.parse_args()
    if a.scans < 1:
        fail("--scans must be >= 1")
    scans = sorted(f[:-4] for f in os.listdir(os.path.join(a.src, "velodyne")) if f.endswith(".bin"))
    if not scans:
        fail(f"{a.src}/velodyne: no .bin scans")
    with open(os.path.join(a.src, "poses.txt")) as f:
        poses = [l for l in f.read().splitlines() if l.strip()]
    if len(poses) != len(scans):
        fail(f"{a.src}/poses.txt: {len(poses)} poses for {len(scans)} scans")
    with open(os.path.join(a.src, "times.txt")) as f:
        times = [float(t) for t in f.read().split()]
    dt = (times[-1] - times[0]) / (len(times) - 1) if len(times) > 1 else 0.1

    n = len(scans)
    period = list(range(n)) + list(range(n - 2, 0, -1)) if n > 1 else [0]
    order = [period[i % len(period)] for i in range(a.scans)]

    if os.path.exists(a.dst):
        fail(f"{a.dst}: exists; choose a new folder")
    subdirs = [(d, ext) for d, ext in (("velodyne", ".bin"), ("labels", ".label"), ("image_2", ".png"))
               if os.path.isdir(os.path.join(a.src, d))]
    for d, _ in subdirs:
        os.makedirs(os.path.join(a.dst, d))
    for i, s in enumerate(order):
        for d, ext in subdirs:
            src = os.path.abspath(os.path.join(a.src, d, scans[s] + ext))
            if os.path.exists(src):
                os.symlink(src, os.path.join(a.dst, d, f"{i:06d}{ext}"))
    with open(os.path.join(a.src, "calib.txt")) as f, open(os.path.join(a.dst, "calib.txt"), "w") as g:
        g.write(f.read())
    with open(os.path.join(a.dst, "poses.txt"), "w") as g:
        g.writelines(poses[s] + "\n" for s in order)
    with open(os.path.join(a.dst, "times.txt"), "w") as g:
        g.writelines(f"{i * dt:.6e}\n" for i in range(a.scans))
    print(f"loop_kitti.py: {a.dst}: {a.scans} scans of {a.src} ({n} scans, forth and back)")


if __name__ == "__main__":
    main()

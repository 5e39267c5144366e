#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Writes a cleanmap-sim scenario of a long straight street, for the memory a long drive takes.

Unlike loop_kitti.py, which drives a short set forth and back over the same ground, every scan
here sees new ground: blocks of buildings on both sides every 40 m, a pole and a parked car
beside each, no movers. The ego drives at --speed m/s for --metres, one scan per 0.1 s. What the
run holds for the whole sequence (the free-space map, DESIGN §2e) grows with the ground covered;
report.json's map.free_space_mib and peak_rss_mib say how much.

usage: long_street.py OUT.ini [--metres 600] [--speed 10] [--seed 3]
then:  cleanmap-sim OUT.ini -o SEQ --no-images --no-rawlog
       cleanmap SEQ -o RUN --quiet --no-mrpt-outputs [--last N]
"""
import argparse
import math
import random
import sys


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--metres", type=float, default=600.0, help="length driven (default 600)")
    ap.add_argument("--speed", type=float, default=10.0, help="m/s (default 10)")
    ap.add_argument("--seed", type=int, default=3, help="seed of the buildings' sizes (default 3)")
    a = ap.parse_args()
    if not (a.metres > 0 and a.speed > 0):
        sys.exit("long_street.py: --metres and --speed must be positive")
    frames = max(1, math.ceil(a.metres / a.speed * 10))
    rnd = random.Random(a.seed)
    end = a.metres + 50  # the street goes on beyond the last scan's crop
    out = ["# Written by datasets/long_street.py: a straight street with new ground in every scan.",
           "[scenario]", "name = long_street", f"frames = {frames}", "rate_hz = 10", "seed = 1", "",
           "[sensor]", "camera = false", "",
           "[ground]", "road_half_width = 6.0", "curb_height = 0.12", "",
           "[ego]", f"path = -10 -2.5  {end:.1f} -2.5", f"speed = {a.speed:g}", ""]
    x, n = -40.0, 0
    while x < end + 60:
        for side in (1, -1):
            w, d, h = rnd.uniform(20, 36), rnd.uniform(6, 12), rnd.uniform(8, 15)
            y = side * (9 + d / 2 + rnd.uniform(0, 3))
            out += ["[box]", f"name = block_{n}", f"center = {x + w / 2:.1f} {y:.1f}",
                    f"size = {w:.1f} {d:.1f} {h:.1f}", ""]
            out += ["[cylinder]", f"center = {x + 5:.1f} {side * 7}", "radius = 0.12",
                    "height = 6", ""]
            out += ["[box]", f"name = parked_{n}", "class = car",
                    f"center = {x + 12:.1f} {side * 4.8}", "size = 4.4 1.8 1.5", ""]
            n += 1
        x += 40
    try:
        with open(a.out, "w") as f:
            f.write("\n".join(out))
    except OSError as e:
        sys.exit(f"long_street.py: {a.out}: {e.strerror}")
    print(f"{a.out}: {frames} frames, {a.metres:g} m at {a.speed:g} m/s, {n} blocks")


if __name__ == "__main__":
    main()

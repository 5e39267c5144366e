#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Runs the shipped simulated scenarios perturbed, to see which results hold beyond them (doc/BENCHMARK.md).

Each scenario of datasets/scenarios/ (or those named) is rewritten per variant, simulated with
cleanmap-sim (no images, no rawlog), run through cleanmap (laser only, no MRPT outputs) and scored
with cleanmap-eval; one line per run: per-point P / R / IoU, map SA / DA / AA, and the share of
each moving object's points labelled moving. Variants:
  base      as shipped              seed      another noise and dropout draw (seed + 10)
  ego_slow  the ego at 0.6x speed   ego_fast  the ego at 1.5x speed
  mov_slow  every mover at 0.5x     mov_fast  every mover at 1.5x
  noisy     twice the range noise   hdl32     an HDL-32E instead of the scene's lidar
  vlp16     a VLP-16 instead of the scene's lidar (not in the default list)
  os1_64, os1_128  an Ouster OS1-64 / OS1-128 instead (1024 columns; not in the default list)
  accel     movers pull away and brake at 2 m/s2 instead of changing speed at once (not in the
            default list; only scenes whose movers wait or stop change)
Variants compose with '+', applied left to right: mov_slow+vlp16 is a VLP-16 seeing every mover at
half speed (at most one lidar in a composition; each variant once). --variants standing names the
set the regression sweeps of doc/BENCHMARK.md run (STANDING below: every variant, and the sparse
and coarse-column lidars with slow movers or a slow ego).
The bars the named tests check are for the shipped scenes; this looks around them. A run's
folders are removed once scored (about 100 MB each); --keep keeps them.

--against APPS2 compares two builds (a change against its base), --against-config INI2 two
configurations (a parameter against the default, or -c's), or both: each line is simulated once
(by --apps' cleanmap-sim) and run both ways; it prints the counts of both and whether their labels
(labels/) and clean maps (static_map_full.ply) are byte-identical, then how many lines differ.

usage: perturb_scenarios.py --apps BUILD/apps -o WORKDIR [--scenarios a,b] [--variants v,w]
                            [--against BUILD2/apps] [--against-config INI2] [-c CONFIG.ini]
                            [--threads N] [--keep]
"""
import argparse
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
VARIANTS = ["base", "seed", "ego_slow", "ego_fast", "mov_slow", "mov_fast", "noisy", "hdl32"]
OPTIONAL = ["vlp16", "os1_64", "os1_128", "os1_64_512", "accel"]  # run only when named
STANDING = VARIANTS + OPTIONAL + ["mov_slow+vlp16", "mov_slow+hdl32", "ego_slow+os1_64_512",
                                  "mov_slow+os1_64_512"]
# variant -> the [sensor] model preset it uses
SENSORS = {"hdl32": "hdl32", "vlp16": "vlp16", "os1_64": "os1-64", "os1_128": "os1-128",
           "os1_64_512": "os1-64"}
COLUMNS = {"os1_64_512": 360 / 512}  # a preset at another column count (degrees between columns)
# (section, key) -> factor, per variant
SCALE = {
    "ego_slow": ("ego", "speed", 0.6),
    "ego_fast": ("ego", "speed", 1.5),
    "mov_slow": ("mover", "speed", 0.5),
    "mov_fast": ("mover", "speed", 1.5),
    "noisy": ("sensor", "range_noise", 2.0),
}


def fail(msg):
    sys.exit(f"perturb_scenarios.py: {msg}")


def perturb(text, variant):
    """The scenario ini rewritten for one variant (doc/SIMULATOR.md's format)."""
    out, section, seen = [], None, set()
    for line in text.splitlines():
        m = re.match(r"\s*\[(\w+)\]", line)
        if m:
            section = m.group(1)
        kv = re.match(r"\s*(\w+)\s*=\s*([^#]*)", line)
        if kv:
            key, value = kv.group(1), kv.group(2).strip()
            seen.add((section, key))
            if variant == "seed" and (section, key) == ("scenario", "seed"):
                line = f"seed = {int(value) + 10}"
            elif variant in SCALE and (section, key) == SCALE[variant][:2]:
                f = SCALE[variant][2]
                line = f"{key} = " + " ".join(f"{float(x) * f:g}" for x in value.split())
            elif variant in SENSORS and section == "sensor" and key in (
                    "model", "azimuth_step_deg", "rings", "vertical_fov_deg"):
                line = "# " + line  # the preset's rings and azimuth step
        out.append(line)
    text = "\n".join(out) + "\n"
    if "[sensor]" not in text:
        text += "[sensor]\n"
    if variant == "seed" and ("scenario", "seed") not in seen:
        text = text.replace("[scenario]", "[scenario]\nseed = 11", 1)
    if variant == "noisy" and ("sensor", "range_noise") not in seen:
        text = text.replace("[sensor]", "[sensor]\nrange_noise = 0.02", 1)  # twice the default
    if variant in SENSORS:
        text = text.replace("[sensor]", f"[sensor]\nmodel = {SENSORS[variant]}", 1)
    if variant in COLUMNS:
        text = text.replace("[sensor]", f"[sensor]\nazimuth_step_deg = {COLUMNS[variant]:g}", 1)
    if variant == "accel":
        text = re.sub(r"^(\s*\[mover\][^\n]*)$", r"\1\naccel = 2", text, flags=re.M)
    return text


def parts_of(variant):
    """The variants a composition (a+b) applies, or a one-line reason it is refused."""
    parts = variant.split("+")
    for p in parts:
        if p not in VARIANTS + OPTIONAL:
            return None, f"{p}: unknown variant (known: {', '.join(VARIANTS + OPTIONAL)})"
    if len(set(parts)) != len(parts):
        return None, f"{variant}: a variant twice"
    if sum(p in SENSORS for p in parts) > 1:
        return None, f"{variant}: more than one lidar"
    return parts, None


def perturbed(text, variant):
    """The scenario ini rewritten for a variant or a composition of them (a+b: a, then b)."""
    parts, why = parts_of(variant)
    if why:
        raise ValueError(why)
    for p in parts:
        text = perturb(text, p)
    return text


def run(cmd, what):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or ["(no message)"])[-1]
        raise RuntimeError(f"{what}: {last}")
    return r.stdout


def digest(paths):
    """sha256 over the files' names and bytes, in the order given."""
    h = hashlib.sha256()
    for p in paths:
        h.update(os.path.basename(p).encode())
        with open(p, "rb") as f:
            h.update(f.read())
    return h.hexdigest()


def outputs_digest(out):
    """(labels, clean map): the digests a comparison of two builds reads."""
    labels = os.path.join(out, "labels")
    return (digest([os.path.join(labels, f) for f in sorted(os.listdir(labels))]),
            digest([os.path.join(out, "static_map_full.ply")]))


def tools_in(apps):
    tools = {t: os.path.join(apps, t) for t in ("cleanmap", "cleanmap-sim", "cleanmap-eval")}
    for t, p in tools.items():
        if not os.access(p, os.X_OK):
            fail(f"{p}: no {t} executable there (build first: make demo)")
    return tools


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--apps", required=True, help="folder holding cleanmap, cleanmap-sim, cleanmap-eval")
    ap.add_argument("-o", "--output", required=True, help="work folder (created)")
    ap.add_argument("--scenarios", default="", help="comma-separated names (default: all shipped)")
    ap.add_argument("--variants", default=",".join(VARIANTS),
                    help="comma-separated, a+b composed, or 'standing' (STANDING)")
    ap.add_argument("--against", help="a second build's apps folder: run both, compare outputs")
    ap.add_argument("--against-config", help="a second configuration: run both, compare outputs")
    ap.add_argument("-c", "--config", help="cleanmap configuration for every run")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--keep", action="store_true", help="keep each run's folders")
    a = ap.parse_args()
    tools = tools_in(a.apps)
    compare = bool(a.against or a.against_config)
    scen_dir = os.path.join(HERE, "scenarios")
    shipped = sorted(f[:-4] for f in os.listdir(scen_dir) if f.endswith(".ini"))
    names = [s for s in a.scenarios.split(",") if s] or shipped
    for s in names:
        if s not in shipped:
            fail(f"{s}: no such scenario in {scen_dir}")
    variants = STANDING if a.variants == "standing" else [v for v in a.variants.split(",") if v]
    if not variants:
        fail("--variants names none (comma-separated names, a+b, or 'standing')")
    for v in variants:
        why = parts_of(v)[1]
        if why:
            fail(why)
    for c in (a.config, a.against_config):
        if c and not os.path.isfile(c):
            fail(f"{c}: no such configuration file")
    # each way: its tools, configuration and output folder's suffix
    ways = [(tools, a.config, "_out")]
    if compare:
        ways.append((tools_in(a.against) if a.against else tools,
                     a.against_config or a.config, "_out2"))
    os.makedirs(a.output, exist_ok=True)
    width = max(9, *(len(v) for v in variants))  # the variant column, composed names included
    failed = differ = 0
    for s in names:
        with open(os.path.join(scen_dir, s + ".ini")) as f:
            text = f.read()
        for v in variants:
            base = os.path.join(a.output, f"{s}_{v}")
            gt = base + "_gt"
            with open(base + ".ini", "w") as f:
                f.write(perturbed(text, v))
            scores, digests = [], []
            try:
                run([tools["cleanmap-sim"], base + ".ini", "-o", gt, "--no-images", "--no-rawlog",
                     "--threads", str(a.threads)], "cleanmap-sim")
                for t, config, suffix in ways:
                    out = base + suffix
                    cmd = [t["cleanmap"], gt, "-o", out, "--quiet", "--threads", str(a.threads),
                           "--images", "off", "--no-mrpt-outputs", "--force"]
                    run(cmd + (["-c", config] if config else []), "cleanmap")
                    scores.append(json.loads(run([t["cleanmap-eval"], gt, out, "--json"],
                                                 "cleanmap-eval")))
                    if compare:
                        digests.append(outputs_digest(out))
            except RuntimeError as e:
                print(f"{s:18} {v:{width}} FAILED {e}", flush=True)
                failed += 1
                continue
            finally:
                if not a.keep:
                    for path in [gt] + [base + suffix for _, _, suffix in ways]:
                        shutil.rmtree(path, ignore_errors=True)
            if compare:
                (la, ma), (lb, mb) = digests
                verdict = ("same" if la == lb and ma == mb else
                           "labels differ" if ma == mb else "map differs" if la == lb else
                           "labels and map differ")
                differ += verdict != "same"
                sides = " | ".join(
                    f"P {j['precision']:.4f} R {j['recall']:.4f} fp {j['counts']['fp']} "
                    f"fn {j['counts']['fn']} AA {j['AA']:.4f}" for j in scores)
                print(f"{s:18} {v:{width}} {sides} | {verdict}", flush=True)
                continue
            j = scores[0]
            objs = " ".join(f"{o['name']}:{o['fraction']:.2f}" for o in j["objects"].get("list", []))
            print(f"{s:18} {v:{width}} P {j['precision']:.3f} R {j['recall']:.3f} IoU {j['iou']:.3f} "
                  f"SA {j['SA']:.4f} DA {j['DA']:.4f} AA {j['AA']:.4f} | {objs}", flush=True)
    if compare:
        print(f"{len(names) * len(variants) - failed} lines compared, {differ} differ", flush=True)
    if failed:
        fail(f"{failed} run(s) failed")


if __name__ == "__main__":
    main()

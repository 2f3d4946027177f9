#!/usr/bin/env python3
"""Do the extension pieces' standard errors cover the truth where the model is the truth?

    python3 scripts/standard-error-calibration.py [--seeds 101-124] [--excitation strokes]
        [--noise 0.02] [--resolution 0] [--jobs 2] [--cli build/apps/friction-identify]

For each effect below and each seed, `friction-identify generate` writes an estimation record
(that seed) and a validation record (seed + 100000) from its reference Maxwell Slip system with
the effect at a fixed value; `identify --model maxwell-slip --extension EFFECT` fits it, and
z = (estimate - truth) / standard error.  Per effect it prints the share of |z| <= 1.96 (95 %
intervals), the median |z| (0.67 for a unit normal) and the mean and spread of z.  This separates
the covariance from model error: the discovery study's records come from another simulator, and
its misses there mix both (README, "The discovery study's coverage").  A by-hand check, not a
test: 120 fits take about 4 minutes on one core.
"""
import argparse
import concurrent.futures
import json
import os
import statistics
import subprocess
import sys
import tempfile

EFFECTS = {  # effect: (generate's --effect, the parameter judged, its true value)
    "viscous": ("viscous=40", "viscous", 40.0),
    "inertia": ("inertia=0.5", "mass", 0.5),
    "offset": ("offset=0.05", "offset", 0.05),
    "asymmetry": ("asymmetry=0.1", "asymmetry", 0.1),
    "delay": ("delay=0.0013", "delay", 0.0013),
}


def seeds_of(text):
    out = []
    for part in text.split(","):
        if "-" in part:
            lo, hi = part.split("-")
            out.extend(range(int(lo), int(hi) + 1))
        else:
            out.append(int(part))
    return out


def one(args, work, effect, seed):
    spec, name, truth = EFFECTS[effect]
    d = os.path.join(work, f"{effect}-{seed}")
    os.makedirs(d, exist_ok=True)
    for tag, s in (("est", seed), ("val", seed + 100000)):
        subprocess.run([args.cli, "generate", "--excitation", args.excitation, "--noise",
                        str(args.noise), "--resolution", str(args.resolution), "--seed", str(s),
                        "--effect", spec, "--out", os.path.join(d, f"{tag}.csv")],
                       check=True, capture_output=True)
    r = subprocess.run([args.cli, "identify", "--model", "maxwell-slip", "--extension", effect,
                        "--data", os.path.join(d, "est.csv"), "--validate",
                        os.path.join(d, "val.csv"), "--format", "json"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        return effect, seed, None, r.stderr.strip()[:200]
    p = json.loads(r.stdout)["extensions"]["pieces"][effect][name]
    se = p.get("standard_error")
    if not se:
        return effect, seed, None, "no standard error"
    return effect, seed, (p["value"] - truth) / se, ""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="101-124")
    ap.add_argument("--excitation", default="strokes")
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--resolution", type=float, default=0.0)
    ap.add_argument("--jobs", type=int, default=2)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument("--cli", default=os.path.join(root, "build", "apps", "friction-identify"))
    args = ap.parse_args()
    if not os.access(args.cli, os.X_OK):
        sys.exit(f"error: {args.cli} is not an executable (build first, or give --cli)")
    seeds = seeds_of(args.seeds)
    with tempfile.TemporaryDirectory() as work:
        with concurrent.futures.ThreadPoolExecutor(args.jobs) as ex:
            results = list(ex.map(lambda job: one(args, work, *job),
                                  [(e, s) for e in EFFECTS for s in seeds]))
    pooled = [0, 0]
    print(f"{'effect':10s} {'covered':>9s} {'median|z|':>9s} {'mean z':>7s} {'sd z':>5s}")
    for effect in EFFECTS:
        zs = [z for e, _, z, _ in results if e == effect and z is not None]
        for e, seed, z, why in results:
            if e == effect and z is None:
                print(f"  {effect} seed {seed}: {why}")
        if not zs:
            continue
        covered = sum(abs(z) <= 1.96 for z in zs)
        pooled[0] += covered
        pooled[1] += len(zs)
        print(f"{effect:10s} {covered:4d}/{len(zs):<4d} {statistics.median(map(abs, zs)):9.2f} "
              f"{statistics.mean(zs):+7.2f} {statistics.pstdev(zs):5.2f}")
    print(f"pooled     {pooled[0]}/{pooled[1]}")


if __name__ == "__main__":
    main()

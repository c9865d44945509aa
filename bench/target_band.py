#!/usr/bin/env python3
"""Does `irfarm render --target-error E` land within issue 6's band [E/2, 2E] of the truth?

For every scene folder given (scene.xml, reference.exr, reference.json) and every E, renders with
`--target-error E --seed SEED`, measures relMSE against the reference (numpy, the benchmarks'
definition), subtracts the reference's own error (reference.json's relmse_est_ref_vs_truth, as
the shared references and bench/make_room.py write it) and prints the truth, the render's own
estimate (stats error_estimate.relmse), its CPU seconds and whether the truth is in the band.

  python3 bench/target_band.py --irfarm build/irfarm --targets 4e-3,1e-3 --seed 7 \
      ../shared/scenes/cornell-box OUT/room-221 ...

The stats JSON of each run stays in --out (default: a temporary folder), with the refinement's
rounds under error_estimate.cache_rounds.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from indirect_only import read_rgb  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="+", help="scene folders")
    ap.add_argument("--irfarm", default=os.path.join(os.path.dirname(__file__), "..", "build",
                                                     "irfarm"))
    ap.add_argument("--targets", default="4e-3,1e-3")
    ap.add_argument("--seed", default="7")
    ap.add_argument("--out", default="")
    ap.add_argument("--args", default="", help="more irfarm render arguments")
    a = ap.parse_args()
    out_dir = a.out or tempfile.mkdtemp(prefix="target_band_")
    os.makedirs(out_dir, exist_ok=True)
    inside = total = 0
    for d in a.scenes:
        name = os.path.basename(os.path.normpath(d))
        ref = read_rgb(os.path.join(d, "reference.exr"))
        with open(os.path.join(d, "reference.json")) as f:
            floor = json.load(f).get("relmse_est_ref_vs_truth", 0.0)
        for e in a.targets.split(","):
            target = float(e)
            img = os.path.join(out_dir, f"{name}_{e}.exr")
            stats = img + ".json"
            subprocess.run([a.irfarm, "render", os.path.join(d, "scene.xml"), "--seed", a.seed,
                            "-q", "--target-error", e, "-o", img, "--stats", stats] +
                           a.args.split(), check=True)
            with open(stats) as f:
                st = json.load(f)
            x = read_rgb(img)
            truth = float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01))) - floor
            est = (st.get("error_estimate") or {}).get("relmse")
            ok = target / 2 <= truth <= 2 * target
            inside += ok
            total += 1
            est_text = f"{est:.2e}" if isinstance(est, float) else str(est)
            print(f"{name:12s} E={e} truth {truth:.2e} est {est_text} "
                  f"cpu {st['cpu_seconds']['total']:.1f}s {'IN' if ok else 'out'}", flush=True)
    print(f"{inside} of {total} in band")


if __name__ == "__main__":
    main()

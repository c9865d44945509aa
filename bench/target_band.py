#!/usr/bin/env python3
"""Does `irfarm render --target-error E` land within issue 6's band [E/2, 2E] of the truth?

The --target-error part of bench/time_vs_error.py alone, for any scene folders (scene.xml,
reference.exr, reference.json): each scene at each E, seed 7, with time_vs_error's render and its
target table (measured relMSE, the render's estimate, both band checks, also with the reference's
own error, reference.json's relmse_est_ref_vs_truth, taken out), the seconds of each run, and the
count in the band against the truth.

  python3 bench/target_band.py --irfarm build/irfarm --targets 4e-3,1e-3 \
      ../shared/scenes/cornell-box OUT/room-221 ...
"""
import argparse
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import time_vs_error as tve  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="+", help="scene folders")
    ap.add_argument("--irfarm", default=os.path.join(os.path.dirname(__file__), "..", "build",
                                                     "irfarm"))
    ap.add_argument("--targets", default="4e-3,1e-3")
    ap.add_argument("--out", default="", help="where the images and stats stay (default: a "
                                              "temporary folder)")
    a = ap.parse_args()
    out_dir = a.out or tempfile.mkdtemp(prefix="target_band_")
    os.makedirs(out_dir, exist_ok=True)
    rows, inside, total = [], 0, 0
    for d in a.scenes:
        name = os.path.basename(os.path.normpath(d))
        runs = []
        for e in a.targets.split(","):
            r = tve.render(a.irfarm, d, ["--target-error", e], out_dir, f"{name}_{e}")
            r["method"] = "irrcache-target"
            runs.append(r)
            truth = r["relmse"] - tve.reference_error(d)
            ok = float(e) / 2 <= truth <= 2 * float(e)
            inside += ok
            total += 1
            print(f"{name:12s} E={e} truth {truth:.2e} est {r['estimate']:.2e} "
                  f"{r['seconds']:.1f} s {'IN' if ok else 'out'}", flush=True)
        rows += tve.target_rows(name, d, runs)
    print("\n".join([""] + tve.TARGET_HEADER + rows))
    print(f"\n{inside} of {total} within [E/2, 2E] against the truth")


if __name__ == "__main__":
    main()

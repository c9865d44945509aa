#!/usr/bin/env python3
"""Indirect-only images at equal record count (issue 9): irfarm's irradiance cache against the
Ward split-sphere cache of main when the issue was filed (the baseline binary, commit f9fc65e,
built with a two-line bench patch: IRFARM_INDIRECT_ONLY=1 keeps only its cached term).

Per scene (all-diffuse scenes only: the cached term is then exactly what is not direct):
  - the indirect reference: the scene's Mitsuba reference minus Mitsuba's direct light, rendered
    here (`mitsuba` package): path with max_depth 2 and the sky (constant or envmap) removed
    (emission seen and light straight from area and directional lights), plus the sky seen by
    the camera (max_depth 1, sky only). irfarm and the baseline cache the sky's light at
    surfaces, so it is indirect here.
    With --indirect-spp N instead: Mitsuba's indirect light rendered directly at N spp by the
    integrator of bench/mitsuba_indirect.py (the same quantity without the noise of the two
    renders it is otherwise the difference of: about 6x less noise per spp on room-224, and no
    samples spent on the direct light).
  - the baseline at its defaults, indirect only: its records and relMSE;
  - irfarm (build/irfarm) with --aovs, its `indirect` layer, over accuracies 0.05 .. 0.4 at the
    record rays and cache levels its default run's pilot chose (--ladder-pilot: each run's
    pilot chooses again, as before 2026-12-05): relMSE against records, read at the baseline's
    record count by log-log interpolation between the two runs around it (never extrapolated);
    and the same ladder at the baseline's own record rays (its stats) and the default run's
    levels: records of equal cost;
  - irfarm at its defaults: relMSE and seconds against the baseline's (equal-time comparison).

  python3 bench/indirect_only.py --baseline-bin WARD/irfarm [--scenes cornell-box,...]
      [--spp 4096] [--out bench-indirect] [--irfarm-args "--spacing hessian"] [--bin 4]
      [--noise-spp 1024] [--indirect-spp 8192] [--ladder-pilot] [--same-rays-levels 1]
      [--seeds 7,8,9]

Building the baseline: `git worktree add WARD f9fc65e`, the patch in docs/bench/indirect-only/
ward-indirect-only.patch (`git -C WARD apply`), `cmake -S WARD -B WARD/build -G Ninja && cmake
--build WARD/build --target irfarm`.
"""
import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

from mitsuba_indirect import mitsuba  # the mitsuba module, its fastest variant that loads here

SCENES = ["cornell-box", "sunlit-room", "thin-panels", "veach-ajar", "room-a", "room-b", "room-c",
          "room-d"]


# --bin B: every image (irfarm's, the baseline's, the indirect reference and the floor's renders)
# is box-filtered by B x B before relMSE is taken. The references are box-filtered renders, so
# their pixels' noise is independent and binning divides its share of every figure by about B^2
# (the single-render floor estimates, which are rough, fell 8x to 30x at 4 x 4), while a cache's
# error (records' noise and interpolation, smooth over many pixels) stays nearly whole.
BIN = 1


def binned(x):
    if BIN <= 1:
        return x
    h, w = x.shape[0] // BIN * BIN, x.shape[1] // BIN * BIN
    return x[:h, :w].reshape(h // BIN, BIN, w // BIN, BIN, -1).mean(axis=(1, 3))


def relmse(x, ref):
    x, ref = binned(x), binned(ref)
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01)))


def read_rgb(path, layer=""):
    import OpenEXR
    f = OpenEXR.File(path)
    for part in f.parts:
        ch = part.channels
        for key in ([layer, layer + ".RGB"] if layer else ["RGB"]):
            if key in ch:
                return np.array(ch[key].pixels, dtype=np.float64)[:, :, :3]
        names = [layer + "." + c if layer else c for c in "RGB"]
        if all(n in ch for n in names):
            return np.stack([np.array(ch[n].pixels, dtype=np.float64) for n in names], axis=-1)
    raise KeyError(f"{path}: no layer '{layer}'")




def direct_reference(scene_dir, spp, out, seed_base=90000):
    """Mitsuba's direct light as irfarm's irrcache splits it (see the module docstring)."""
    if os.path.exists(out):
        return np.load(out)
    mi = mitsuba()
    xml = open(os.path.join(scene_dir, "scene.xml")).read()
    sky = re.compile(r'<emitter type="(?:constant|envmap)".*?</emitter>', re.S)
    no_sky = sky.sub("", xml)
    # The sky alone: every other emitter removed.
    emitters = re.compile(r'<emitter type="(?!constant|envmap)[a-z]+".*?</emitter>', re.S)
    sky_only = emitters.sub("", xml)

    # The scene's relative paths (meshes, textures) resolve against its folder.
    mi.Thread.thread().file_resolver().prepend(os.path.abspath(scene_dir))

    def render(text, depth, n):
        s = mi.load_string(text, max_depth=depth)
        chunk = min(n, 256)
        return np.mean([np.array(mi.render(s, spp=chunk, seed=seed_base + k), dtype=np.float64)
                        [:, :, :3] for k in range(n // chunk)], axis=0)

    d = render(no_sky, 2, spp)
    if sky.search(xml):
        d = d + render(sky_only, 1, 64)
    np.save(out, d)
    return d


def reference_floor(scene_dir, ind_ref, n, cache, direct=None, direct_spp=0, out_dir="."):
    """The indirect reference's own noise in this measure: the relMSE (indirect denominators) that
    its noise adds to any image compared with it. Two independent parts, each from an independent
    Mitsuba render at n spp compared with what it estimates, E[(m - r)^2] = var_m + var_r with
    var_m = var_r * spp_r / n, so r's part is that relMSE / (1 + spp_r / n): the scene's reference
    (against a full render) and the direct render `direct` at direct_spp (against a direct render
    with other seeds). Cached in `cache`."""
    if os.path.exists(cache):
        with open(cache) as f:
            return json.load(f)["floor"]
    mi = mitsuba()
    with open(os.path.join(scene_dir, "reference.json")) as f:
        spp_ref = json.load(f)["spp"]
    s = mi.load_file(os.path.join(scene_dir, "scene.xml"))
    chunk = min(n, 256)
    m = np.mean([np.array(mi.render(s, spp=chunk, seed=70000 + k), dtype=np.float64)[:, :, :3]
                 for k in range(n // chunk)], axis=0)
    ref = read_rgb(os.path.join(scene_dir, "reference.exr"))
    m, ref, ind_b = binned(m), binned(ref), binned(ind_ref)
    e = float(np.mean((m - ref) ** 2 / (ind_b ** 2 + 0.01)))
    floor_ref = e / (1 + spp_ref / n)
    floor_direct = 0.0
    if direct is not None:
        name = os.path.basename(os.path.normpath(scene_dir))
        d2 = direct_reference(scene_dir, n, os.path.join(out_dir, name + "-direct-check.npy"),
                              seed_base=190000)
        e2 = float(np.mean((binned(d2) - binned(direct)) ** 2 / (ind_b ** 2 + 0.01)))
        floor_direct = e2 / (1 + direct_spp / n)
    floor = floor_ref + floor_direct
    with open(cache, "w") as f:
        json.dump({"floor": floor, "reference_part": floor_ref, "direct_part": floor_direct,
                   "mitsuba_spp": n, "reference_spp": spp_ref, "direct_spp": direct_spp,
                   "relmse_mitsuba_vs_reference": e}, f)
    return floor


def run(binary, scene_dir, args, tmp, tag, env=None, settings=None, seed=7):
    out = os.path.join(tmp, tag + ".exr")
    stats = os.path.join(tmp, tag + ".json")
    subprocess.run([binary, "render", os.path.join(scene_dir, "scene.xml"), "-o", out, "--stats",
                    stats, "-q", "--seed", str(seed)] + args, check=True, capture_output=True,
                   env=dict(os.environ, **(env or {})))
    with open(stats) as f:
        st = json.load(f)
    secs = sum(st["seconds"].get(k, 0) for k in ("pilot", "overture", "render"))
    if settings is not None:
        settings.update(st.get("settings", {}))
    return out, st["records"]["computed"], secs


def measure(seeds, binary, scene_dir, args, tmp, tag, ref, layer="", env=None, settings=None):
    """run() once per seed: the mean records, seconds and relMSE against `ref` (of the image's
    `layer`). `settings` receives the first seed's."""
    got = []
    for k, seed in enumerate(seeds):
        img, n, t = run(binary, scene_dir, args, tmp, f"{tag}-{seed}", env,
                        settings if k == 0 else None, seed)
        got.append((n, t, relmse(read_rgb(img, layer), ref)))
    n, t, e = (sum(g[i] for g in got) / len(got) for i in range(3))
    return int(round(n)), t, e


def indirect_reference(scene_dir, spp, cache, seed_base=50000):
    """Mitsuba's indirect light rendered directly (bench/mitsuba_indirect.py), cached in `cache`."""
    if os.path.exists(cache):
        return np.load(cache)
    from mitsuba_indirect import render_indirect
    img = render_indirect(scene_dir, spp, seed_base)
    np.save(cache, img)
    return img


def indirect_floor(scene_dir, ind_ref, spp_ref, n, cache):
    """The directly rendered indirect reference's own noise in this measure, from an independent
    render at n spp (other seeds): E[(m - r)^2] = var_r (1 + spp_r / n)."""
    if os.path.exists(cache):
        with open(cache) as f:
            return json.load(f)["floor"]
    m = indirect_reference(scene_dir, n, cache.replace(".json", ".npy"), seed_base=150000)
    e = relmse(m, ind_ref)
    floor = e / (1 + spp_ref / n)
    with open(cache, "w") as f:
        json.dump({"floor": floor, "indirect_spp": spp_ref, "mitsuba_spp": n,
                   "relmse_mitsuba_vs_reference": e}, f)
    return floor


def at_records(points, n):
    """relMSE at record count n from [(records, relmse)], log-log between the two around n."""
    pts = sorted(points)
    for (r0, e0), (r1, e1) in zip(pts, pts[1:]):
        if r0 <= n <= r1 and r0 != r1:
            f = (math.log(n) - math.log(r0)) / (math.log(r1) - math.log(r0))
            return math.exp(math.log(e0) + f * (math.log(e1) - math.log(e0)))
    return None


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--irfarm", default=os.path.join(here, "..", "build", "irfarm"))
    ap.add_argument("--baseline-bin", required=True)
    ap.add_argument("--scenes-dir", default=os.path.join(here, "..", "..", "shared", "scenes"))
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--accuracies", default="0.05,0.07,0.1,0.14,0.2,0.3,0.4")
    ap.add_argument("--spp", type=int, default=4096, help="Mitsuba direct-light spp")
    ap.add_argument("--noise-spp", type=int, default=0,
                    help="estimate the reference's own noise in this measure from a Mitsuba "
                         "render at this spp, and report ratios with it subtracted")
    ap.add_argument("--summarize", metavar="RUNS_JSON",
                    help="no renders: the table from an earlier run's runs.json")
    ap.add_argument("--irfarm-args", default="",
                    help="extra irfarm render arguments, e.g. '--spacing hessian'")
    ap.add_argument("--bin", type=int, default=1,
                    help="box-filter every image by BIN x BIN before relMSE (see BIN above)")
    ap.add_argument("--indirect-spp", type=int, default=0,
                    help="render the indirect reference directly at this spp "
                         "(bench/mitsuba_indirect.py) instead of the scene's reference minus "
                         "Mitsuba's direct light")
    ap.add_argument("--ladder-pilot", action="store_true",
                    help="let every ladder run's pilot choose its own rays and levels (before "
                         "2026-12-05) instead of the default run's")
    ap.add_argument("--same-rays-levels", type=int, choices=[1, 2, 3], default=0,
                    help="cache levels of the ladder at the baseline's rays (default: the "
                         "default run's; 1: one level, as the baseline's cache)")
    ap.add_argument("--seeds", default="7",
                    help="comma-separated seeds: every figure (records, seconds, relMSE; the "
                         "baseline's too) is the mean over them (one run's ladder reading moves "
                         "by about 0.1 from run to run)")
    ap.add_argument("--out", default="bench-indirect")
    a = ap.parse_args()
    global BIN
    BIN = a.bin
    seeds = [int(s) for s in a.seeds.split(",")]
    os.makedirs(a.out, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix="irfarm-indirect-")
    rows = []
    if a.summarize:
        with open(a.summarize) as f:
            rows = json.load(f)
    for name in ([] if a.summarize else a.scenes.split(",")):
        d = os.path.join(a.scenes_dir, name)
        if a.indirect_spp:
            ind_ref = indirect_reference(
                d, a.indirect_spp, os.path.join(a.out, f"{name}-indirect-{a.indirect_spp}.npy"))
        else:
            ref = read_rgb(os.path.join(d, "reference.exr"))
            direct = direct_reference(d, a.spp, os.path.join(a.out, name + "-direct.npy"))
            ind_ref = ref - direct
        base_settings = {}
        n_base, t_base, e_base = measure(seeds, a.baseline_bin, d, [], tmp, name + "-base",
                                         ind_ref, env={"IRFARM_INDIRECT_ONLY": "1"},
                                         settings=base_settings)
        print(f"{name:12s} baseline      records {n_base:7d} {t_base:7.2f} s relMSE {e_base:.3e}",
              flush=True)
        extra = a.irfarm_args.split()
        chosen = {}
        n_def, t_def, e_def = measure(seeds, a.irfarm, d, ["--aovs"] + extra, tmp, name + "-def",
                                      ind_ref, "indirect", settings=chosen)
        # The ladder varies the accuracy alone, at the rays and cache levels the default run's
        # pilot chose (each ladder run's own pilot would choose again, and a curve through
        # runs of different rays and levels is not one cache's error against its records).
        fixed = [] if a.ladder_pilot or "record_rays" not in chosen else [
            "--record-rays", str(chosen["record_rays"]), "--cache-levels",
            str(chosen["cache_levels"])]
        if fixed:
            print(f"{name:12s} ladder at the default run's {' '.join(fixed)}", flush=True)
        print(f"{name:12s} irfarm default records {n_def:7d} {t_def:7.2f} s relMSE {e_def:.3e}",
              flush=True)
        pts = [(n_def, e_def)]
        timed = [(t_def, e_def)]
        for acc in a.accuracies.split(","):
            n, t, e = measure(seeds, a.irfarm, d, ["--aovs", "--accuracy", acc] + fixed + extra,
                              tmp, name + "-a" + acc, ind_ref, "indirect")
            pts.append((n, e))
            timed.append((t, e))
            print(f"{name:12s} irfarm a={acc:5s} records {n:7d} {t:7.2f} s relMSE {e:.3e}",
                  flush=True)
        e_eq = at_records(pts, n_base)
        # The same ladder at the baseline's own record rays (and the cache levels the default
        # run chose): records of equal cost, so that where they are put, how they are
        # interpolated and what the record rays find beyond their first bounce differ. (With two
        # levels, the second level's records count too, as everywhere here (stats
        # records.computed), each as one record though it has a fraction of the rays: they stand
        # in for the bounces the baseline path-traces.)
        pts_same = []
        if not a.ladder_pilot and "record_rays" in base_settings and "cache_levels" in chosen:
            same = ["--record-rays", str(base_settings["record_rays"]), "--cache-levels",
                    str(a.same_rays_levels or chosen["cache_levels"])]
            for acc in a.accuracies.split(","):
                n, t, e = measure(seeds, a.irfarm, d, ["--aovs", "--accuracy", acc] + same + extra,
                                  tmp, name + "-s" + acc, ind_ref, "indirect")
                pts_same.append((n, e))
                print(f"{name:12s} irfarm a={acc:5s} {' '.join(same)} records {n:7d} "
                      f"{t:7.2f} s relMSE {e:.3e}", flush=True)
        e_same = at_records(pts_same, n_base) if pts_same else None
        # Equal time: the lowest relMSE of the runs that took no longer than the baseline.
        within = [e for t, e in timed if t <= t_base]
        e_time = min(within) if within else None
        rows.append({"scene": name, "baseline_records": n_base, "baseline_seconds": t_base,
                     "baseline_relmse": e_base, "irfarm_default_records": n_def,
                     "irfarm_default_seconds": t_def, "irfarm_default_relmse": e_def,
                     "irfarm_at_baseline_records": e_eq, "irfarm_within_baseline_time": e_time,
                     "points": pts, "timed": timed,
                     "irfarm_at_baseline_records_same_rays": e_same, "points_same_rays": pts_same,
                     "baseline_record_rays": base_settings.get("record_rays")})
    for r in rows:
        if a.noise_spp and a.indirect_spp:
            d = os.path.join(a.scenes_dir, r["scene"])
            ind = indirect_reference(
                d, a.indirect_spp, os.path.join(a.out, f"{r['scene']}-indirect-{a.indirect_spp}.npy"))
            r["reference_floor"] = indirect_floor(
                d, ind, a.indirect_spp, a.noise_spp,
                os.path.join(a.out, r["scene"] + "-indirect-floor.json"))
            print(f"{r['scene']:12s} reference floor {r['reference_floor']:.3e}", flush=True)
        elif a.noise_spp:
            d = os.path.join(a.scenes_dir, r["scene"])
            direct = direct_reference(d, a.spp, os.path.join(a.out, r["scene"] + "-direct.npy"))
            ind = read_rgb(os.path.join(d, "reference.exr")) - direct
            r["reference_floor"] = reference_floor(
                d, ind, a.noise_spp, os.path.join(a.out, r["scene"] + "-floor.json"), direct,
                a.spp, a.out)
            print(f"{r['scene']:12s} reference floor {r['reference_floor']:.3e}", flush=True)
    same_levels = {0: "the default run's levels", 1: "one level", 2: "two levels"}[
        a.same_rays_levels]
    lines = ["| scene | baseline (Ward, f9fc65e): records, rays, s, relMSE | irfarm at the "
             f"baseline's records and rays, {same_levels}: relMSE (ratio) | irfarm at the baseline's "
             "records, the default run's rays and levels: relMSE (ratio) | irfarm in at most the "
             "baseline's time: best relMSE (ratio) | irfarm default: records, s, relMSE (ratio) | "
             "reference floor: equal-records ratios with it subtracted |",
             "|---|---|---|---|---|---|---|"]

    def ratio(e, r):
        return f"{e:.2e} ({e / r['baseline_relmse']:.2f})" if e else "outside the measured records"

    def floored(e, r):
        f = r["reference_floor"]
        return f"{(e - f) / (r['baseline_relmse'] - f):.2f}" if e else "-"

    for r in rows:
        eq = r["irfarm_at_baseline_records"]
        es = r.get("irfarm_at_baseline_records_same_rays")
        et = r["irfarm_within_baseline_time"]
        lines.append(
            f"| {r['scene']} | {r['baseline_records']}, {r.get('baseline_record_rays', '?')}, "
            f"{r['baseline_seconds']:.2f} s, {r['baseline_relmse']:.2e} | " +
            (ratio(es, r) if r.get("points_same_rays") else "not run") +
            " | " + ratio(eq, r) + " | " +
            (f"{et:.2e} ({et / r['baseline_relmse']:.2f})" if et else "no run that fast") + " | " +
            f"{r['irfarm_default_records']}, {r['irfarm_default_seconds']:.2f} s, "
            f"{r['irfarm_default_relmse']:.2e} "
            f"({r['irfarm_default_relmse'] / r['baseline_relmse']:.2f}) | " +
            (f"{r['reference_floor']:.2e}: {floored(es, r)} / {floored(eq, r)}"
             if r.get("reference_floor") is not None else "-") + " |")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(a.out, "summary.md"), "w") as f:
        f.write(text)
    with open(os.path.join(a.out, "runs.json" if not a.summarize else "runs-floor.json"),
              "w") as f:
        json.dump(rows, f, indent=1)
    print(text)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Error against time, side by side in one run: irfarm with and without --denoise against
Mitsuba 3 + Open Image Denoise (issue 8).

For each scene with a Mitsuba reference (../shared/scenes/<name>/reference.exr):
  - irfarm: each setting is rendered once with --aovs; the render is the undenoised point and
    `irfarm denoise --mode M` of it gives the denoised points (time = render + denoise).
  - Mitsuba 3 (the scene's own path integrator) at 4, 16, 64, 256 spp, its albedo and shading
    normal from a separate render of the `aov` integrator alone at the same spp, then OIDN 2
    (pyoidn: RT filter, hdr, albedo + normal), when the `mitsuba` and `pyoidn` packages are
    installed. Times are mi.render wall seconds (path, then the guides) after a warm-up render at
    the same spp (JIT compiled), plus OIDN's seconds. The guides are rendered apart because
    wrapping the path integrator in `aov` doubles Mitsuba's render time (cornell-box 16 spp:
    1.0-1.1 s against 0.5 s for path alone and 0.02 s for the guides), which a user who wants
    speed would not pay.
Prints a table of relMSE (mean((x - ref)^2 / (ref^2 + 0.01)) over pixels and channels) and
seconds, writes bench-denoise.json and one log-log error-vs-time PNG per scene.

  pip install mitsuba pyoidn numpy matplotlib
  python3 bench/denoise_bench.py --irfarm build/irfarm --out bench-denoise [--scenes a,b]
The llvm_ad_rgb variant needs an LLVM shared library (Debian: apt-get install libllvm19,
DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so); without one, --variant scalar_rgb.
"""
import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

SCENES = ["cornell-box", "sunlit-room", "specular", "thin-panels", "veach-ajar",
          "room-a", "room-b", "room-c", "room-d", "living-room"]
# irfarm settings: (label, extra render arguments).
IRFARM_SETTINGS = [
    ("irrcache default", []),
    # `render --denoise` itself, the integrator left to irfarm: path where its pilots find the
    # cache's own error would stay after the denoiser (record_balance.h, ChooseForDenoising); the
    # stats' integrator is printed. Samples stay in their pixel, as --denoise renders them.
    ("default --denoise", ["--denoise"]),
    ("irrcache 16spp", ["--spp", "16"]),
    ("path 16spp", ["--integrator", "path", "--spp", "16"]),
    ("path 64spp", ["--integrator", "path", "--spp", "64"]),
]
DENOISE_MODES = ["image", "demodulated"]
MITSUBA_SPP = [4, 16, 64, 256]


def relmse(x, ref):
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01)))


def irfarm_relmse(irfarm, test, ref_path):
    """relMSE of an EXR's R, G, B against the reference, as `irfarm compare` computes it."""
    r = subprocess.run([irfarm, "compare", test, ref_path], check=True, capture_output=True,
                       text=True)
    return json.loads(r.stdout)["relmse"]


def read_rgb_exr(path):
    import mitsuba as mi  # Bitmap reads a 3-channel EXR
    return np.array(mi.Bitmap(path), dtype=np.float32)[:, :, 0:3]


def run_irfarm(args, scene, ref_path, label, extra, outdir):
    base = os.path.join(outdir, scene + "-" + label.replace(" ", "_"))
    stats = base + ".json"
    cmd = [args.irfarm, "render", os.path.join(args.scenes_dir, scene, "scene.xml"), "-o",
           base + ".exr", "--aovs", "-q", "--stats", stats] + extra
    subprocess.run(cmd, check=True)
    with open(stats) as f:
        stats_json = json.load(f)
    st = stats_json["seconds"]
    seconds = st.get("pilot", 0) + st.get("overture", 0) + st["render"]
    if "--denoise" in extra:  # OUT.exr denoised by the render itself, OUT.noisy.exr as rendered
        integrator = stats_json["integrator"]
        return [{"renderer": "irfarm", "setting": label, "denoise": "none",
                 "integrator": integrator, "seconds": seconds,
                 "relmse": irfarm_relmse(args.irfarm, base + ".noisy.exr", ref_path)},
                {"renderer": "irfarm", "setting": label, "denoise": "image",
                 "integrator": integrator, "seconds": seconds + st.get("denoise", 0),
                 "denoise_seconds": st.get("denoise", 0),
                 "relmse": irfarm_relmse(args.irfarm, base + ".exr", ref_path)}]
    points = [{"renderer": "irfarm", "setting": label, "denoise": "none",
               "seconds": seconds, "relmse": irfarm_relmse(args.irfarm, base + ".exr", ref_path)}]
    for mode in DENOISE_MODES:
        out = base + "." + mode + ".exr"
        r = subprocess.run([args.irfarm, "denoise", base + ".exr", out, "--mode", mode],
                           check=True, capture_output=True, text=True)
        dsec = json.loads(r.stdout)["denoise_seconds"]
        points.append({"renderer": "irfarm", "setting": label, "denoise": mode,
                       "seconds": seconds + dsec, "denoise_seconds": dsec,
                       "relmse": irfarm_relmse(args.irfarm, out, ref_path)})
    return points


def oidn_denoise(pyoidn, color, albedo, normal):
    out = np.zeros_like(color)
    dev = pyoidn.Device()
    dev.commit()
    flt = pyoidn.Filter(dev, "RT")
    flt.set_image(pyoidn.OIDN_IMAGE_COLOR, color, pyoidn.OIDN_FORMAT_FLOAT3)
    flt.set_image(pyoidn.OIDN_IMAGE_ALBEDO, albedo, pyoidn.OIDN_FORMAT_FLOAT3)
    flt.set_image(pyoidn.OIDN_IMAGE_NORMAL, normal, pyoidn.OIDN_FORMAT_FLOAT3)
    flt.set_image(pyoidn.OIDN_IMAGE_OUTPUT, out, pyoidn.OIDN_FORMAT_FLOAT3)
    flt.set_bool("hdr", True)
    flt.commit()
    flt.execute()
    err = dev.get_error()
    flt.release()
    dev.release()
    if err:
        raise RuntimeError("OIDN: " + str(err))
    return out


def run_mitsuba(args, scene, ref_path):
    import mitsuba as mi
    import pyoidn
    mi.set_variant(args.variant)
    ref = read_rgb_exr(ref_path)
    path = os.path.join(args.scenes_dir, scene, "scene.xml")
    s = mi.load_file(path)
    path_integ = s.integrator()
    guides = mi.load_dict({"type": "aov", "aovs": "albedo:albedo,nn:sh_normal"})
    points = []
    for spp in MITSUBA_SPP:
        # Above 64 spp, chunks of 64 with different seeds, averaged (with a box filter exactly
        # one render at the total spp), so that the 64-spp kernel is reused without a costly
        # warm-up at 256.
        chunk = min(spp, 64)
        if spp <= 64:  # warm-up: JIT compile both kernels at this spp
            mi.render(s, integrator=path_integ, spp=chunk, seed=7)
            mi.render(s, integrator=guides, spp=chunk, seed=7)
        t = time.time()
        out = np.mean([np.array(mi.render(s, integrator=path_integ, spp=chunk,
                                          seed=1234 + spp + k))
                       for k in range(spp // chunk)], axis=0)
        render_s = time.time() - t
        t = time.time()
        aux = np.array(mi.render(s, integrator=guides, spp=chunk, seed=4321 + spp))
        guides_s = time.time() - t
        color = np.ascontiguousarray(out[:, :, 0:3], dtype=np.float32)
        # aov integrator output: R, G, B, A, then the AOVs in order (albedo, normal).
        albedo = np.ascontiguousarray(aux[:, :, -6:-3], dtype=np.float32)
        normal = np.ascontiguousarray(aux[:, :, -3:], dtype=np.float32)
        oidn_denoise(pyoidn, color, albedo, normal)  # warm-up (weights loading)
        t = time.time()
        den = oidn_denoise(pyoidn, color, albedo, normal)
        oidn_s = time.time() - t
        points.append({"renderer": "mitsuba", "setting": f"{spp}spp", "denoise": "none",
                       "spp": spp, "seconds": render_s, "relmse": relmse(color, ref)})
        points.append({"renderer": "mitsuba", "setting": f"{spp}spp", "denoise": "oidn",
                       "spp": spp, "seconds": render_s + guides_s + oidn_s,
                       "guides_seconds": guides_s, "denoise_seconds": oidn_s,
                       "relmse": relmse(den, ref)})
    return points


def plot(scene, points, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    curves = {}
    for p in points:
        key = (p["renderer"] + " " + (p["setting"] if p["renderer"] == "irfarm" else "")).strip()
        key += "" if p["denoise"] == "none" else " + " + p["denoise"]
        curves.setdefault(key, []).append(p)
    for i, (key, ps) in enumerate(sorted(curves.items())):
        ps = sorted(ps, key=lambda q: q["seconds"])
        # Mitsuba: lines through its spp points; irfarm: one marker per setting, the marker
        # telling undenoised (square), denoised whole (circle) and demodulated (triangle).
        style = "-o" if key.startswith("mitsuba") else (
            "^" if key.endswith("demodulated") else "o" if key.endswith("image") else "s")
        ax.loglog([q["seconds"] for q in ps], [q["relmse"] for q in ps], style, label=key,
                  markersize=5, color=plt.cm.tab20(i % 20))
    ax.set_xlabel("seconds (render + denoise; same run, same machine)")
    ax.set_ylabel("relMSE vs reference")
    ax.set_title(scene)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def mitsuba_time_for(points, target):
    """Seconds Mitsuba + OIDN needs for relMSE `target`: log-log interpolation along its curve
    (None when the target is below its 256-spp point, inf... when above its 4-spp point, its
    4-spp time is an upper bound)."""
    curve = sorted((p["seconds"], p["relmse"]) for p in points
                   if p["renderer"] == "mitsuba" and p["denoise"] == "oidn")
    for (t0, e0), (t1, e1) in zip(curve, curve[1:]):
        if e1 <= target <= e0:
            if e0 == e1:
                return t0
            f = (np.log(target) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return float(np.exp(np.log(t0) + f * (np.log(t1) - np.log(t0))))
    if curve and target >= curve[0][1]:
        return curve[0][0]
    return None


def summarize(results):
    """Per scene: Mitsuba + OIDN at 16 spp against irfarm's settings; where --denoise is worse."""
    print("\nsummary: irfarm (denoise mode 'image') against Mitsuba + OIDN 16 spp")
    print(f"  {'scene':12} {'Mitsuba+OIDN 16spp':>22} | {'irfarm setting':17} "
          f"{'relMSE':>9} {'sec':>6} | Mitsuba+OIDN sec at that relMSE")
    worse = []
    for scene, points in results.items():
        m16 = [p for p in points if p["renderer"] == "mitsuba" and p["setting"] == "16spp"
               and p["denoise"] == "oidn"]
        for p in points:
            if p["renderer"] != "irfarm" or p["denoise"] == "none":
                continue
            base = [q for q in points if q["renderer"] == "irfarm" and
                    q["setting"] == p["setting"] and q["denoise"] == "none"][0]
            if p["relmse"] > base["relmse"]:
                worse.append((scene, p["setting"], p["denoise"], base["relmse"], p["relmse"]))
            if p["denoise"] != "image" or not m16:
                continue
            t = mitsuba_time_for(points, p["relmse"])
            print(f"  {scene:12} {m16[0]['relmse']:10.2e} {m16[0]['seconds']:7.2f} s    | "
                  f"{p['setting']:17} {p['relmse']:9.2e} {p['seconds']:6.2f} | "
                  + ("below Mitsuba 256spp+OIDN" if t is None else f"{t:.2f}"))
    print("\n--denoise worse than the same render undenoised:",
          "never" if not worse else "")
    for w in worse:
        print("  %s %s mode %s: %.3e -> %.3e" % w)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--irfarm", default=os.path.join(here, "..", "build", "irfarm"))
    ap.add_argument("--scenes-dir", default=os.path.join(here, "..", "..", "shared", "scenes"))
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--out", default="bench-denoise")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--no-mitsuba", action="store_true")
    ap.add_argument("--summarize", metavar="JSON",
                    help="only print the summary of a past run and redraw its plots into --out")
    args = ap.parse_args()
    if not os.path.isdir(args.scenes_dir):
        sys.exit(f"--scenes-dir {args.scenes_dir}: no such folder (a clone has none by default); pass "
                 "the folder that holds SCENE/scene.xml and SCENE/reference.exr: the shared "
                 "scenes, or rooms made by bench/make_room.py")
    os.makedirs(args.out, exist_ok=True)
    if args.summarize:
        with open(args.summarize) as f:
            results = json.load(f)["results"]
        for scene, points in results.items():
            plot(scene, points, os.path.join(args.out, scene + ".png"))
        summarize(results)
        return
    try:
        import mitsuba  # noqa: F401
        import pyoidn  # noqa: F401
        have_mitsuba = not args.no_mitsuba
    except ImportError as e:
        print(f"Mitsuba + OIDN skipped ({e}); pip install mitsuba pyoidn", file=sys.stderr)
        have_mitsuba = False
    results = {}
    for scene in args.scenes.split(","):
        ref_path = os.path.join(args.scenes_dir, scene, "reference.exr")
        points = []
        for label, extra in IRFARM_SETTINGS:
            points += run_irfarm(args, scene, ref_path, label, extra, args.out)
        if have_mitsuba:
            points += run_mitsuba(args, scene, ref_path)
        results[scene] = points
        print(f"\n{scene}")
        print(f"  {'renderer':8} {'setting':17} {'denoise':12} {'seconds':>8} {'relMSE':>10}")
        for p in points:
            print(f"  {p['renderer']:8} {p['setting']:17} {p['denoise']:12} "
                  f"{p['seconds']:8.2f} {p['relmse']:10.3e}"
                  + (f"  ({p['integrator']})" if "integrator" in p else ""))
        sys.stdout.flush()
        plot(scene, points, os.path.join(args.out, scene + ".png"))
        with open(os.path.join(args.out, "bench-denoise.json"), "w") as f:
            json.dump({"load_average": os.getloadavg(), "results": results}, f, indent=1)
    summarize(results)


if __name__ == "__main__":
    main()

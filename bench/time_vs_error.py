#!/usr/bin/env python3
"""Error against time, side by side in one run, for every scene folder given.

For each scene (default: every folder of ../shared/scenes with a reference.exr and a
mitsuba-curve.json), this renders with the `irfarm` CLI:
  - irfarm path over an spp ladder (default 16, 64, 256),
  - irfarm irrcache at its defaults and over a ladder of settings: --target-error values and
    fixed-spp runs,
  - optionally an older irfarm binary at its defaults (--baseline-bin: "today's" figures), and
    irrcache's error at the baseline's time: the least relMSE of irrcache's runs (default, budgets,
    targets) that took at most the baseline's time (more time never costs error on that ladder;
    nothing is interpolated; 'n/a' when every run took longer), and with --baseline-spp the
    baseline's own curve read at irrcache's default time (log-log between its measured points),
and reads Mitsuba 3's own curve from mitsuba-curve.json (its seconds are from another day and
machine; only ratios measured in this run are sound, and the table says which is which).
Each render's time is the wall time of its overture + render phases (stats JSON); its error is
relMSE = mean((x - ref)^2 / (ref^2 + 0.01)) against the scene's reference (`irfarm compare`).

It writes OUT/<scene>.json (every run), OUT/<scene>.png (log-log error against time, when
matplotlib is installed) and OUT/summary.md: per scene, irrcache's default run, the time path and
Mitsuba need for the same relMSE, read off their measured curves by log-log interpolation between
the two measured points around it (never extrapolated: a relMSE outside a curve's measured range
is reported as '> t_max' or '< t_min'), and the ratios.

With --curve-levels HI,LO it also checks, per scene, that irrcache's curve (the front of its
default and ladder runs) lies below path's at every error level from HI down to LO, from this
run's measured points only (a level outside a curve's range is a bound, never an extrapolation).

  python3 bench/time_vs_error.py --irfarm build/irfarm --out bench-out [--scenes room-a,...]
      [--mitsuba-live 16,64,256]   # Mitsuba 3 in the same run (pip install mitsuba; llvm_ad_rgb
                                   # needs DRJIT_LIBLLVM_PATH, e.g. Debian's libllvm19)
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile


def run(cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True)


def render(irfarm, scene_dir, args, tmp, tag):
    out = os.path.join(tmp, tag + ".exr")
    stats = os.path.join(tmp, tag + ".json")
    run([irfarm, "render", os.path.join(scene_dir, "scene.xml"), "-o", out, "--stats", stats,
         "-q", "--seed", "7"] + args)
    with open(stats) as f:
        st = json.load(f)
    cmp = json.loads(run([irfarm, "compare", out, os.path.join(scene_dir, "reference.exr")])
                     .stdout)
    # The render pipeline's work: the caustic map, the pilot, the overture and the final pass
    # (not loading and building the scene, which Mitsuba's timing leaves out too).
    secs = sum(st["seconds"].get(k, 0) for k in ("caustics", "pilot", "overture", "render"))
    est = st.get("error_estimate", {}).get("relmse")
    spp = st.get("sampling", {}).get("spp_mean", st.get("spp"))
    return {"seconds": secs, "relmse": cmp["relmse"], "estimate": est, "spp_mean": spp,
            "records": st["records"]["computed"], "args": args,
            "nonfinite_samples": st.get("sampling", {}).get("nonfinite_samples")}


def time_for(curve, relmse):
    """Seconds a curve [(seconds, relmse)] needs for `relmse`, by log-log interpolation between
    its measured neighbours; (value, '') inside, (bound, '>' or '<') outside its range."""
    pts = sorted(curve, key=lambda p: p[0])
    errs = [p[1] for p in pts]
    if relmse > max(errs):
        return min(p[0] for p in pts), "<"
    if relmse < min(errs):
        return max(p[0] for p in pts), ">"
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        lo, hi = min(e0, e1), max(e0, e1)
        if lo <= relmse <= hi and e0 != e1:
            f = (math.log(relmse) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0))), ""
    return pts[0][0], ""


def error_within(runs, seconds):
    """The least relMSE of irrcache's runs that took at most `seconds`, or None."""
    within = [r["relmse"] for r in runs
              if r["method"] in ("irrcache", "irrcache-target") and r["seconds"] <= seconds]
    return min(within) if within else None


def error_at(curve, seconds):
    """relMSE of a curve [(seconds, relmse)] at `seconds`, by log-log interpolation between the
    measured points around it in time; (value, '') inside, (bound, '<=' or '>=') outside."""
    pts = sorted(curve)
    if seconds >= pts[-1][0]:
        return (pts[-1][1], "" if seconds == pts[-1][0] else "<=")
    if seconds <= pts[0][0]:
        return (pts[0][1], "" if seconds == pts[0][0] else ">=")
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if t0 <= seconds <= t1 and t1 > t0:
            f = (math.log(seconds) - math.log(t0)) / (math.log(t1) - math.log(t0))
            return math.exp(math.log(e0) + f * (math.log(e1) - math.log(e0))), ""
    return pts[0][1], ""


def baseline_curve(runs):
    return [(r["seconds"], r["relmse"]) for r in runs if r["method"] == "baseline"]


def equal_time_cell(runs, base):
    e = error_within(runs, base["seconds"])
    cell = "n/a" if e is None else f"{e:.2e} ({e / base['relmse']:.2f}x)"
    curve = baseline_curve(runs)
    if len(curve) > 1:  # the baseline's ladder (--baseline-spp): its error at irrcache's time
        default = runs[0]
        eb, flag = error_at(curve, default["seconds"])
        cell += (f"; baseline at irrcache's {default['seconds']:.2f} s: {flag}{eb:.2e} "
                 f"(irrcache {default['relmse'] / eb:.2f}x)")
    return cell


def front(points):
    """The points no other point beats in both time and error: [(seconds, relmse)] by time."""
    pts = sorted(points)
    out = []
    for t, e in pts:
        if not out or e < out[-1][1]:
            out.append((t, e))
    return out


def curve_below(irr, path, hi, lo, levels=13):
    """Is irrcache's measured curve below path's at every error level from `hi` down to `lo`
    (log-spaced)? irr and path are [(seconds, relmse)]; irrcache's curve is the front of its
    settings (the fastest setting for each error). Per level: the seconds each needs, from its
    measured points only, as bounds where a level lies outside a curve's measured range:
    irrcache's cheapest run already below the level reaches it in at most that run's time; path's
    ladder not reaching the level needs more than its slowest run. A level is 'yes' only when
    irrcache's time (or upper bound) is below path's time (or lower bound); 'unknown' where the
    bounds point the wrong way (path's cheapest run already below the level, or irrcache not
    reaching it). Returns (rows, all_yes)."""
    irr_f = front(irr)
    rows, ok = [], True
    for k in range(levels):
        level = math.exp(math.log(hi) + k / (levels - 1) * (math.log(lo) - math.log(hi)))
        ti, fi = time_for(irr_f, level)
        tp, fp = time_for(path, level)
        if fi == ">" or fp == "<":
            verdict = "unknown"
        else:
            verdict = "yes" if ti < tp else "no"
        ok = ok and verdict == "yes"
        rows.append((level, ti, fi, tp, fp, verdict))
    return rows, ok


def mitsuba_curve(scene_dir):
    path = os.path.join(scene_dir, "mitsuba-curve.json")
    if not os.path.exists(path):
        return []
    with open(path) as f:
        d = json.load(f)
    pts = d.get("points", d)
    return [(p.get("seconds_median", p.get("seconds")), p["relmse_mean"], p["spp"]) for p in pts]


def mitsuba_live(scene_dir, ladder, variant):
    """Mitsuba 3 rendered in this run: [(seconds, relMSE, spp)], mi.render wall seconds after a
    warm-up render at the same spp (JIT compilation), relMSE against the same reference."""
    import time
    import numpy as np
    import mitsuba as mi
    mi.set_variant(variant)
    ref = np.array(mi.Bitmap(os.path.join(scene_dir, "reference.exr")), dtype=np.float64)[:, :, :3]
    scene = mi.load_file(os.path.join(scene_dir, "scene.xml"))
    pts = []
    # Above 64 spp, chunks of 64 with different seeds, averaged (with a box filter exactly one
    # render at the total spp): Mitsuba's LLVM wavefront over all samples at once is slower
    # (cornell-box 1024 spp in one call: 52.6 s; chunked it is what a user after speed would run).
    for spp in ladder:
        chunk = min(spp, 64)
        mi.render(scene, spp=chunk, seed=7)  # warm-up: JIT compile at this spp
        t = time.time()
        img = np.mean([np.array(mi.render(scene, spp=chunk, seed=1000 + spp + k),
                                dtype=np.float64)[:, :, :3] for k in range(spp // chunk)], axis=0)
        secs = time.time() - t
        pts.append((secs, float(np.mean((img - ref) ** 2 / (ref ** 2 + 0.01))), spp))
        print(f"  mitsuba live {spp:4d} spp {secs:8.2f} s relMSE {pts[-1][1]:.3e}", flush=True)
    return pts


def plot(scene, runs, mitsuba, path):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, ax = plt.subplots(figsize=(6, 4.5))
    groups = {}
    for r in runs:
        groups.setdefault(r["method"], []).append(r)
    styles = {"path": "o-", "irrcache": "s-", "irrcache-target": "^-", "baseline": "x"}
    for name, rs in groups.items():
        rs = sorted(rs, key=lambda r: r["seconds"])
        ax.plot([r["seconds"] for r in rs], [r["relmse"] for r in rs], styles.get(name, "o-"),
                label="irfarm " + name)
    if mitsuba:
        ax.plot([m[0] for m in mitsuba], [m[1] for m in mitsuba], "d--", label="Mitsuba 3")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall seconds (2 cores)")
    ax.set_ylabel("relMSE vs reference")
    ax.set_title(scene)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True


def reference_error(scene_dir):
    """The reference's own relMSE against the truth (reference.json's relmse_est_ref_vs_truth:
    half the relMSE between its two halves, halved again for the whole), or 0 when unknown. A
    render's relMSE against the reference is, in expectation, its error plus this."""
    try:
        with open(os.path.join(scene_dir, "reference.json")) as f:
            return float(json.load(f).get("relmse_est_ref_vs_truth", 0.0))
    except (OSError, ValueError):
        return 0.0


def target_rows(name, scene_dir, runs):
    """One row per --target-error run: E, measured relMSE, its estimate, and the checks of issue 6
    (measured within [E/2, 2E]; estimate within 1.5x of measured), also with the reference's own
    error taken out of the measured figure (the estimate is of the error against the truth)."""
    ref = reference_error(scene_dir)
    rows = []
    for r in runs:
        if r["method"] != "irrcache-target":
            continue
        e = float(r["args"][r["args"].index("--target-error") + 1])
        m, est = r["relmse"], r["estimate"]
        mt = max(m - ref, 0.0)
        within = lambda x: e / 2 <= x <= 2 * e
        close = lambda x: est > 0 and x > 0 and max(x / est, est / x) <= 1.5
        rows.append(f"| {name} | {e:g} | {m:.2e} | {est:.2e} | {m / est:.2f} | "
                    f"{'yes' if within(m) else 'NO'} | {'yes' if close(m) else 'NO'} | "
                    f"{ref:.1e} | {mt:.2e} | {mt / est:.2f} | {'yes' if within(mt) else 'NO'} | "
                    f"{'yes' if close(mt) else 'NO'} |")
    return rows


TARGET_HEADER = [
    "| scene | E | measured | estimate | measured / estimate | in [E/2, 2E] | estimate within "
    "1.5x | reference's own error | measured - reference's | that / estimate | in [E/2, 2E] | "
    "estimate within 1.5x |",
    "|---|---|---|---|---|---|---|---|---|---|---|---|"]


def summarize_targets(run_dir, scenes_dir):
    """The target table of a stored run (its SCENE.json files), against scenes_dir's references."""
    rows = []
    for fn in sorted(os.listdir(run_dir)):
        if not fn.endswith(".json"):
            continue
        with open(os.path.join(run_dir, fn)) as f:
            j = json.load(f)
        rows += target_rows(j["scene"], os.path.join(scenes_dir, j["scene"]), j["runs"])
    return TARGET_HEADER + rows


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--irfarm", default=os.path.join(here, "..", "build", "irfarm"))
    ap.add_argument("--baseline-bin", help="an older irfarm binary to run at its defaults")
    ap.add_argument("--baseline-spp", default="",
                    help="the baseline also at these --spp (its curve: its error at irrcache's "
                         "default time, interpolated, never extrapolated)")
    ap.add_argument("--scenes-dir", default=os.path.join(here, "..", "..", "shared", "scenes"))
    ap.add_argument("--scenes", help="comma-separated names (default: all with a reference)")
    ap.add_argument("--path-spp", default="16,64,256")
    ap.add_argument("--targets", default="4e-3,1e-3")
    ap.add_argument("--irrcache-spp", default="16,64", help="fixed-spp irrcache runs")
    ap.add_argument("--irrcache-budgets", default="",
                    help="irrcache runs with adaptive sampling at these --spp (the average)")
    ap.add_argument("--out", default="bench-out")
    ap.add_argument("--curve-levels", default="",
                    help="HI,LO: check irrcache's curve below path's at every error level from HI "
                         "down to LO (issue 9: 1e-2,2e-4), from this run's measured points")
    ap.add_argument("--mitsuba-live", default="",
                    help="render Mitsuba 3 in this run at these spp (e.g. 16,64,256) with "
                         "--mitsuba-variant (needs `pip install mitsuba`) instead of its curve file")
    ap.add_argument("--mitsuba-variant", default="llvm_ad_rgb")
    ap.add_argument("--summarize-targets", default="",
                    help="only print the --target-error table of a stored run's directory (its "
                         "SCENE.json files) against --scenes-dir's references, and exit")
    a = ap.parse_args()
    if not os.path.isdir(a.scenes_dir):
        sys.exit(f"--scenes-dir {a.scenes_dir}: no such folder (a clone has none by default); pass "
                 "the folder that holds SCENE/scene.xml and SCENE/reference.exr: the shared "
                 "scenes, or rooms made by bench/make_room.py")
    if a.summarize_targets:
        print("\n".join(summarize_targets(a.summarize_targets, a.scenes_dir)))
        return

    names = a.scenes.split(",") if a.scenes else sorted(
        n for n in os.listdir(a.scenes_dir)
        if os.path.exists(os.path.join(a.scenes_dir, n, "reference.exr"))
        and (a.mitsuba_live or os.path.exists(os.path.join(a.scenes_dir, n, "mitsuba-curve.json"))))
    os.makedirs(a.out, exist_ok=True)
    summary = ["| scene | irrcache default: relMSE, s | path time at that relMSE | "
               "Mitsuba time at that relMSE | Mitsuba 256 spp relMSE | "
               "vs path | vs Mitsuba | baseline default: relMSE, s | "
               "irrcache within the baseline's time: relMSE (vs baseline) | targets " +
               " / ".join(x for x in a.targets.split(",") if x) + ": measured (estimate) |",
               "|---|---|---|---|---|---|---|---|---|---|"]
    tmp = tempfile.mkdtemp(prefix="irfarm-bench-")
    curves = []
    target_table = []
    for name in names:
        d = os.path.join(a.scenes_dir, name)
        runs = []

        def add(method, r):
            r["method"] = method
            runs.append(r)
            print(f"  {name:14s} {method:16s} {' '.join(r['args']):32s} {r['seconds']:8.2f} s "
                  f"relMSE {r['relmse']:.3e}" +
                  (f" est {r['estimate']:.2e}" if r.get("estimate") else ""), flush=True)

        try:
            add("irrcache", render(a.irfarm, d, [], tmp, name + "-irr"))
            for spp in [x for x in a.irrcache_spp.split(",") if x]:
                add("irrcache", render(a.irfarm, d, ["--spp", spp, "--adaptive", "off"], tmp,
                                       name + "-irr" + spp))
            for spp in [x for x in a.irrcache_budgets.split(",") if x]:
                add("irrcache", render(a.irfarm, d, ["--spp", spp], tmp, name + "-irrb" + spp))
            for t in [x for x in a.targets.split(",") if x]:
                add("irrcache-target", render(a.irfarm, d, ["--target-error", t], tmp,
                                              name + "-t" + t))
            for spp in [x for x in a.path_spp.split(",") if x]:
                add("path", render(a.irfarm, d, ["--integrator", "path", "--spp", spp], tmp,
                                   name + "-path" + spp))
        except subprocess.CalledProcessError as e:
            print(f"{name}: {e.stderr.strip()}", file=sys.stderr)
            continue
        try:  # an older binary may not load a newer scene: the rest of the row stands
            if a.baseline_bin:
                add("baseline", render(a.baseline_bin, d, [], tmp, name + "-base"))
                for spp in [x for x in a.baseline_spp.split(",") if x]:
                    add("baseline", render(a.baseline_bin, d, ["--spp", spp], tmp,
                                           name + "-base" + spp))
        except subprocess.CalledProcessError as e:
            print(f"{name}: baseline failed: {e.stderr.strip()}", file=sys.stderr)
        mit = mitsuba_curve(d)
        mit_source = "curve file"
        if a.mitsuba_live:
            try:
                mit = mitsuba_live(d, [int(x) for x in a.mitsuba_live.split(",")],
                                   a.mitsuba_variant)
                mit_source = "live, this run"
            except Exception as e:  # no mitsuba package, or no LLVM for the variant
                print(f"{name}: Mitsuba live failed ({e}); using its curve file", file=sys.stderr)
        default = runs[0]
        path_curve = [(r["seconds"], r["relmse"]) for r in runs if r["method"] == "path"]
        t_path, path_flag = (time_for(path_curve, default["relmse"]) if path_curve else
                             (float("nan"), ""))
        t_mit, mit_flag = time_for([(m[0], m[1]) for m in mit], default["relmse"]) if mit else (
            float("nan"), "")
        mit256 = next((m[1] for m in mit if m[2] == 256), float("nan"))
        base = next((r for r in runs if r["method"] == "baseline"), None)
        targets = [r for r in runs if r["method"] == "irrcache-target"]
        summary.append(
            f"| {name} | {default['relmse']:.2e}, {default['seconds']:.2f} s | "
            f"{path_flag}{t_path:.2f} s | {mit_flag}{t_mit:.2f} s ({mit_source}) | {mit256:.2e} | "
            f"{path_flag}{t_path / default['seconds']:.1f}x | "
            f"{mit_flag}{t_mit / default['seconds']:.1f}x | " +
            (f"{base['relmse']:.2e}, {base['seconds']:.2f} s" if base else "-") + " | " +
            (equal_time_cell(runs, base) if base else "-") + " | " +
            " / ".join(f"{r['relmse']:.2e} ({r['estimate']:.2e})" for r in targets) + " |")
        target_table += target_rows(name, d, runs)
        with open(os.path.join(a.out, name + ".json"), "w") as f:
            json.dump({"scene": name, "runs": runs,
                       "mitsuba_curve": [{"seconds": m[0], "relmse": m[1], "spp": m[2]}
                                         for m in mit], "mitsuba_source": mit_source,
                       "equal_error": {"irrcache_default_relmse": default["relmse"],
                                       "irrcache_default_seconds": default["seconds"],
                                       "path_seconds": t_path, "path_flag": path_flag,
                                       "mitsuba_seconds": t_mit, "mitsuba_flag": mit_flag},
                       "equal_time_vs_baseline": (
                           {"baseline_relmse": base["relmse"], "baseline_seconds": base["seconds"],
                            "irrcache_relmse_within": error_within(runs, base["seconds"]),
                            "baseline_at_irrcache_seconds": (
                                error_at(baseline_curve(runs), default["seconds"])
                                if len(baseline_curve(runs)) > 1 else None)}
                           if base else None)},
                      f, indent=1)
        plot(name, runs, mit, os.path.join(a.out, name + ".png"))
        if a.curve_levels and path_curve:
            hi, lo = (float(x) for x in a.curve_levels.split(","))
            irr = [(r["seconds"], r["relmse"]) for r in runs
                   if r["method"] in ("irrcache", "irrcache-target")]
            rows, ok = curve_below(irr, path_curve, hi, lo)
            curves.append(f"{name}: irrcache below path at every level {hi:g} .. {lo:g}: "
                          + ("YES" if ok else "NO"))
            curves.append("  level      irrcache s   path s      below")
            for level, ti, fi, tp, fp, verdict in rows:
                curves.append(f"  {level:.2e}  {fi or ' '}{ti:9.2f}  {fp or ' '}{tp:9.2f}   {verdict}")
    text = "\n".join(summary) + "\n" + ("\n" + "\n".join(curves) + "\n" if curves else "")
    if target_table:
        text += "\n" + "\n".join(TARGET_HEADER + target_table) + "\n"
    with open(os.path.join(a.out, "summary.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()

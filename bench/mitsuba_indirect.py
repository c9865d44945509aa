#!/usr/bin/env python3
"""Mitsuba 3's indirect light, rendered directly: the part of the image irfarm's irradiance cache
holds (its `indirect` AOV in all-diffuse scenes), as a reference for bench/indirect_only.py.

The integrator `indirect_path` is Mitsuba's path tracer (emitter sampling with MIS, Russian
roulette from depth 5) that adds a path's light only where irfarm's cache would hold it:
  - nothing the camera sees directly (emitters, the sky);
  - at the first surface: only the sky's light (constant or envmap: infinite emitters that are
    not delta lights), by emitter sampling and by BSDF sampling, MIS-weighted as usual;
  - from the second surface on: every light.
That is the scene's image minus Mitsuba's direct light as bench/indirect_only.py's direct render
splits it (path at max_depth 2 without the sky, plus the sky seen by the camera), but without
the noise of the two renders it is the difference of: the lamps' and the sun's direct light is
never sampled, so none of its noise enters. A test against that difference:

  python3 bench/mitsuba_indirect.py SCENE_DIR --spp 1024 --out X.npy [--check-against Y.npy]

Mitsuba's llvm_ad_rgb variant when it loads (DRJIT_LIBLLVM_PATH), else scalar_rgb.
"""
import argparse
import os

import numpy as np


def mitsuba():
    """The mitsuba module with its fastest variant that loads here."""
    import mitsuba as m
    for v in ("llvm_ad_rgb", "scalar_rgb"):
        try:
            m.set_variant(v)
            break
        except Exception:
            continue
    return m


_REGISTERED = False
mi = dr = None  # set by register(): dr.syntax's rewritten loops read module globals


def mis_weight(a, b):
    a2, b2 = dr.square(a), dr.square(b)
    w = a2 / (a2 + b2)
    return dr.detach(dr.select(dr.isfinite(w), w, 0))


def register():
    """Registers `indirect_path` with Mitsuba (once)."""
    global _REGISTERED, mi, dr
    mi = mitsuba()
    if _REGISTERED:
        return mi
    import drjit as dr

    class IndirectPath(mi.SamplingIntegrator):
        def __init__(self, props):
            super().__init__(props)
            self.max_depth = props.get("max_depth", 64)
            self.rr_depth = props.get("rr_depth", 5)

        @dr.syntax
        def sample(self, scene, sampler, ray, medium=None, active=True):
            bsdf_ctx = mi.BSDFContext()
            ray = mi.Ray3f(ray)
            depth = mi.UInt32(0)
            L = mi.Spectrum(0)
            beta = mi.Spectrum(1)
            active = mi.Bool(active)
            si_prev = dr.zeros(mi.SurfaceInteraction3f)
            bsdf_pdf_prev = mi.Float(1.0)
            bsdf_delta_prev = mi.Bool(True)
            while dr.hint(active, max_iterations=self.max_depth, label="IndirectPath"):
                si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=(depth == 0))
                bsdf = si.bsdf(ray)
                # Light found by the previous vertex's BSDF sample: kept from the second vertex
                # on, and at the first vertex only the sky's.
                ds = mi.DirectionSample3f(scene, si=si, ref=si_prev)
                em_flags = ds.emitter.flags()
                sky_hit = mi.has_flag(em_flags, mi.EmitterFlags.Infinite) & \
                    ~mi.has_flag(em_flags, mi.EmitterFlags.Delta)
                keep_hit = (depth >= 2) | ((depth == 1) & sky_hit)
                mis = mis_weight(bsdf_pdf_prev,
                                 scene.pdf_emitter_direction(si_prev, ds, ~bsdf_delta_prev))
                Le = beta * mis * ds.emitter.eval(si, active & keep_hit)
                L = L + dr.select(keep_hit, Le, 0)

                active_next = active & (depth + 1 < self.max_depth) & si.is_valid()
                # Emitter sampling at this vertex: at the first vertex only the sky's.
                active_em = active_next & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
                ds_em, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(), True,
                                                                  active_em)
                active_em &= ds_em.pdf != 0.0
                f_em = ds_em.emitter.flags()
                sky_em = mi.has_flag(f_em, mi.EmitterFlags.Infinite) & \
                    ~mi.has_flag(f_em, mi.EmitterFlags.Delta)
                active_em &= (depth >= 1) | sky_em
                wo = si.to_local(ds_em.d)
                bsdf_val, bsdf_pdf = bsdf.eval_pdf(bsdf_ctx, si, wo, active_em)
                mis_em = dr.select(ds_em.delta, 1.0, mis_weight(ds_em.pdf, bsdf_pdf))
                L = L + dr.select(active_em, beta * mis_em * bsdf_val * em_weight, 0)

                bs, bsdf_weight = bsdf.sample(bsdf_ctx, si, sampler.next_1d(), sampler.next_2d(),
                                              active_next)
                ray = si.spawn_ray(si.to_world(bs.wo))
                beta *= bsdf_weight
                si_prev = si
                bsdf_pdf_prev = bs.pdf
                bsdf_delta_prev = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
                beta_max = dr.max(mi.unpolarized_spectrum(beta))
                active_next &= beta_max != 0
                rr_prob = dr.minimum(beta_max, 0.95)
                rr_active = depth >= self.rr_depth
                beta[rr_active] *= dr.rcp(rr_prob)
                active_next &= ~rr_active | (sampler.next_1d() < rr_prob)
                depth += 1
                active = active_next
            return L, mi.Bool(True), []

        def aov_names(self):
            return []

        def to_string(self):
            return "IndirectPath[]"

    mi.register_integrator("indirect_path", lambda props: IndirectPath(props))
    _REGISTERED = True
    return mi


def render_indirect(scene_dir, spp, seed_base=50000, chunk=256):
    """The scene's indirect light at `spp` samples per pixel (float64 H x W x 3), rendered in
    chunks of `chunk` spp with seeds seed_base, seed_base + 1, ..."""
    mi = register()
    import re
    xml = open(os.path.join(scene_dir, "scene.xml")).read()
    xml = re.sub(r'<integrator type="[a-z_]+"\s*/>',
                 '<integrator type="indirect_path"/>', xml)
    xml = re.sub(r'<integrator type="[a-z_]+"\s*>.*?</integrator>',
                 '<integrator type="indirect_path"/>', xml, flags=re.S)
    if 'type="indirect_path"' not in xml:
        xml = xml.replace("</scene>", '<integrator type="indirect_path"/>\n</scene>')
    mi.file_resolver().prepend(os.path.abspath(scene_dir))
    scene = mi.load_string(xml)
    chunk = min(chunk, spp)
    acc = None
    for k in range(spp // chunk):
        img = np.array(mi.render(scene, spp=chunk, seed=seed_base + k), dtype=np.float64)[..., :3]
        acc = img if acc is None else acc + img
    return acc / (spp // chunk)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene_dir")
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--seed", type=int, default=50000)
    ap.add_argument("--out", required=True, help=".npy to write")
    ap.add_argument("--check-against",
                    help="a .npy of the same scene's indirect light to compare with (e.g. "
                         "bench/indirect_only.py's reference minus direct, saved with np.save)")
    a = ap.parse_args()
    img = render_indirect(a.scene_dir, a.spp, a.seed)
    np.save(a.out, img)
    print(f"{a.out}: mean {img.mean():.5f}, non-finite {int((~np.isfinite(img)).sum())}")
    if a.check_against:
        other = np.load(a.check_against)
        e = float(np.mean((img - other) ** 2 / (other ** 2 + 0.01)))
        print(f"relMSE against {a.check_against}: {e:.3e}; means {img.mean():.5f} "
              f"{other.mean():.5f}")


if __name__ == "__main__":
    main()

#include "render/path_tracer.h"

namespace irfarm {

Vec3 TracePath(const Scene& scene, Ray ray, int depth, bool skip_first_local_emission,
               const PathSettings& settings, Rng& rng, RenderCounters& counters,
               float* first_distance, SampleAov* aov) {
  Vec3 L, beta(1, 1, 1);
  float prev_pdf = 0;   // solid-angle pdf of the BSDF sample that made `ray`; 0 = delta/camera
  Vec3 prev_p, prev_n;  // the previous vertex and its facing normal (light selection weights)
  float eta_scale = 1;
  bool first = true;
  // AOVs: depth of the first non-specular vertex (-1: not reached yet), and the path length so
  // far. A contribution made at vertex `d` is direct up to one vertex past that one.
  int diffuse_depth = -1;
  float path_length = 0;
  if (aov) *aov = SampleAov{};
  const auto add = [&](const Vec3& c, int d) {
    L += c;
    if (!aov) return;
    if (diffuse_depth < 0) aov->emission += c;
    (diffuse_depth < 0 || d <= diffuse_depth + 1 ? aov->direct : aov->indirect) += c;
  };
  for (;; ++depth) {
    SurfaceHit hit;
    if (!scene.Intersect(ray, &hit)) {
      if (first && first_distance) *first_distance = INFINITY;
      if (scene.has_environment()) {
        const bool skip_mis = prev_pdf == 0 || (first && skip_first_local_emission);
        const float w =
            skip_mis ? 1.0f
                     : PowerHeuristic(prev_pdf, scene.PdfEnvironment(prev_p, prev_n, ray.dir));
        add(beta * scene.EvalEnvironment(ray.dir) * w, depth);
      }
      break;
    }
    if (first && first_distance) *first_distance = hit.t;
    path_length += hit.t;
    const Vec3 wo = -ray.dir;
    if (hit.light >= 0 && !(first && skip_first_local_emission)) {
      const Vec3 le = scene.Emitted(hit, wo);
      if (!IsBlack(le)) {
        const float w =
            prev_pdf == 0
                ? 1.0f
                : PowerHeuristic(prev_pdf, scene.PdfAreaLight(prev_p, prev_n, hit, ray.dir));
        add(beta * le * w, depth);
      }
    }
    first = false;
    if (settings.max_depth >= 0 && depth >= settings.max_depth) break;
    const Material& mat = scene.material(hit.material);
    Vec3 nf;
    if (!FacingNormal(mat, hit.ns, wo, &nf)) break;  // one-sided surface seen from the back

    Vec3 wi;
    const bool can_extend = settings.max_depth < 0 || depth + 1 <= settings.max_depth;
    if (mat.IsDelta()) {
      const BsdfSample bs = SampleDelta(mat, hit.ns, wo, rng.Next());
      beta *= bs.weight;
      eta_scale *= bs.eta * bs.eta;
      wi = bs.wi;
      prev_pdf = 0;
    } else {
      const Vec3 albedo = mat.Albedo(hit.u, hit.v);
      if (aov && diffuse_depth < 0) {
        diffuse_depth = depth;
        aov->albedo = beta * albedo;
        aov->normal = nf;
        aov->depth = path_length;
      }
      if (can_extend) {  // next-event estimation
        LightSample ls;
        const float u1 = rng.Next(), u2 = rng.Next(), u3 = rng.Next();
        int skipped = 0;
        const bool sampled = scene.SampleLight(hit.p, nf, u1, u2, u3, true, &ls, &skipped);
        counters.lights_skipped += uint64_t(skipped);
        if (sampled) {
          const float cos_i = Dot(ls.wi, nf);
          if (cos_i > 0 && Dot(ls.wi, hit.ng) * Dot(wo, hit.ng) > 0) {
            ++counters.shadow_rays;
            if (!scene.Occluded(Scene::SpawnShadowRay(hit, ls))) {
              const float bsdf_pdf = cos_i * kInvPi;
              const float w = ls.pdf == 0 ? 1.0f : PowerHeuristic(ls.pdf, bsdf_pdf);
              add(beta * albedo * ls.value * (cos_i * kInvPi * w), depth);
            }
          }
        }
      }
      Vec3 s, t;
      MakeFrame(nf, &s, &t);
      const float u = rng.Next();
      const float v = rng.Next();  // drawn in order: argument evaluation order is unspecified
      const Vec3 local = CosineHemisphere(u, v);
      wi = s * local.x + t * local.y + nf * local.z;
      prev_pdf = local.z * kInvPi;
      beta *= albedo;
    }
    if (!can_extend) break;
    // A direction on the other side of the geometric surface than the shading normal promised
    // would pass through the surface: stop (reflection) unless the material transmits.
    const bool transmits = Dot(wi, hit.ng) * Dot(wo, hit.ng) < 0;
    if (transmits && mat.type != BsdfType::kDielectric && mat.type != BsdfType::kThinDielectric)
      break;
    if (IsBlack(beta)) break;
    if (depth >= settings.rr_depth) {
      const float q = std::min(MaxComponent(beta) * eta_scale, 0.95f);
      if (rng.Next() >= q) break;
      beta /= q;
    }
    prev_p = hit.p;
    prev_n = nf;
    ray = Scene::SpawnRay(hit.p, hit.ng, hit.error_scale, wi);
    ++counters.bounce_rays;
  }
  return L;
}

}  // namespace irfarm

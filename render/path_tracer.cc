#include "render/path_tracer.h"

namespace irfarm {

Vec3 TracePath(const Scene& scene, Ray ray, int depth, bool skip_first_local_emission,
               const PathSettings& settings, Rng& rng, RenderCounters& counters,
               float* first_distance, SampleAov* aov, Vec3* first_environment) {
  Vec3 L, beta(1, 1, 1);
  float prev_pdf = 0;   // solid-angle pdf of the BSDF sample that made `ray`; 0 = delta/camera
  Vec3 prev_p, prev_n;  // the previous vertex and the normal it selected lights with
  float eta_scale = 1;
  bool first = true;
  if (first_environment) *first_environment = Vec3();
  // With a caustic map (settings.caustics, whose photons follow its lobes M): the part of beta
  // whose scatterings since the last diffuse one (or the start) all went through M, and the same
  // through the sampled direction (what emission found there is then a caustic at that diffuse
  // vertex, the map's). And whether a light is the map's.
  const CausticMap* map = settings.caustics;
  const uint32_t caustic_lobes = map != nullptr ? map->lobes() : 0u;
  Vec3 beta_caustic = map != nullptr ? Vec3(1, 1, 1) : Vec3(), beta_caustic_next;
  const auto mapped = [&](int light) { return map != nullptr && CausticMap::Covers(scene, light); };
  const LightSampler& lights = scene.light_sampler();
  // PathSettings::direct_sun: whether the vertex `ray` left took a sample of the sun (the first
  // segment: the record point's direct light does), so its directions' light is not counted
  // again where the ray escapes.
  const EnvironmentSun* sun = settings.direct_sun;
  bool sun_sampled = sun != nullptr && skip_first_local_emission;
  // AOVs: depth of the first non-specular vertex (-1: not reached yet), and the path length so
  // far. A contribution made at vertex `d` is direct up to one vertex past that one.
  int diffuse_depth = -1;
  float path_length = 0;
  if (aov) *aov = SampleAov{};
  // Mitsuba's path with max_depth 0 renders nothing, not even emitters seen by the camera.
  if (settings.max_depth == 0) return L;
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
      if (scene.has_environment() && !(sun_sampled && sun->Contains(ray.dir))) {
        const bool skip_mis = prev_pdf == 0 || (first && skip_first_local_emission);
        const float w = skip_mis ? 1.0f
                                 : PowerHeuristic(prev_pdf, lights.NeePdfEnvironment(
                                                                settings.all_lights, prev_p, prev_n,
                                                                ray.dir, settings.env_importance));
        // The environment's sun reached through the map's lobes only is the map's caustic.
        const Vec3 throughput =
            map != nullptr && !IsBlack(beta_caustic_next) && map->CoversEnvironment(ray.dir)
                ? beta - beta_caustic_next
                : beta;
        const Vec3 c = throughput * scene.EvalEnvironment(ray.dir) * w;
        add(c, depth);
        if (first && first_environment) *first_environment = c;
      }
      break;
    }
    path_length += hit.t;
    // The first segment's length, across the masks and panes it passed straight through.
    if (first && first_distance) *first_distance = path_length;
    const Vec3 wo = -ray.dir;
    if (hit.light >= 0 && !(first && skip_first_local_emission)) {
      const Vec3 le = scene.Emitted(hit, wo);
      const Vec3 throughput = mapped(hit.light) ? beta - beta_caustic_next : beta;
      if (!IsBlack(le) && !IsBlack(throughput)) {
        const float w =
            prev_pdf == 0
                ? 1.0f
                : PowerHeuristic(prev_pdf, lights.NeePdfArea(settings.all_lights, prev_p, prev_n,
                                                             hit.light, hit.p, hit.ns, hit.prim,
                                                             ray.dir, settings.coarse_light_tree));
        add(throughput * le * w, depth);
      }
    }
    const bool was_first = first;
    first = false;
    if (settings.max_depth >= 0 && depth >= settings.max_depth) break;
    const Bsdf& bsdf = scene.material(hit.material);
    const BsdfContext ctx = hit.Context();
    const ShadingFrame frame = hit.Frame();
    const Vec3 wo_l = frame.ToLocal(wo);
    const bool can_extend = settings.max_depth < 0 || depth + 1 <= settings.max_depth;
    if (!can_extend) break;
    // The facing normal: the side wo is on (light selection weighs lights by it, unless the
    // BSDF transmits: LightSelectionNormal).
    const Vec3 nf = wo_l.z >= 0 ? hit.ns : -hit.ns;
    const Vec3 n_select = LightSelectionNormal(bsdf.Flags(), nf);

    if (aov && diffuse_depth < 0 && bsdf.HasSmooth()) {  // the first non-specular surface
      diffuse_depth = depth;
      aov->albedo = beta * bsdf.DiffuseAlbedo(ctx, wo_l);
      aov->normal = nf;
      aov->depth = path_length;
    }
    // The caustic arriving here (the map's), through the diffuse lobe.
    if (map != nullptr) {
      const Vec3 albedo = bsdf.DiffuseAlbedo(ctx, wo_l);
      if (!IsBlack(albedo)) add(beta * albedo * kInvPi * map->Irradiance(hit.p, nf), depth + 1);
    }
    // One light sample, MIS-weighted against BSDF sampling (a delta light's sample: weight 1).
    const auto shade_light = [&](const LightSample& ls) {
      if (ls.environment && sun != nullptr && sun->Contains(ls.wi)) return;  // the sun sample's
      const Vec3 wi_l = frame.ToLocal(ls.wi);
      if (!SidesAgree(wo, ls.wi, hit.ng, wo_l.z, wi_l.z)) return;
      const Vec3 f = bsdf.Eval(ctx, wo_l, wi_l);
      if (IsBlack(f)) return;
      Vec3 c = beta * f;
      if (!IsBlack(beta_caustic) &&
          (ls.environment ? map->CoversEnvironment(ls.wi) : mapped(ls.light))) {
        c -= beta_caustic * bsdf.Eval(ctx, wo_l, wi_l, caustic_lobes);
        if (IsBlack(c)) return;
      }
      ++counters.shadow_rays;
      if (scene.ShadowOccluded(hit, ls)) return;
      const float w = ls.pdf == 0 ? 1.0f : PowerHeuristic(ls.pdf, bsdf.Pdf(ctx, wo_l, wi_l));
      add(c * scene.LightValue(ls) * w, depth);
    };
    if (bsdf.HasSmooth()) {  // next-event estimation, MIS against BSDF sampling
      lights.SampleForNee(settings.all_lights, settings.env_importance, hit.p, n_select, rng,
                          &counters.lights_skipped, shade_light, settings.coarse_light_tree);
      if (sun != nullptr) {  // the environment's sun: one sample, the only estimate of its light
        LightSample ls;
        float pdf;
        ls.environment = true;
        sun->Sample(rng.Next(), rng.Next(), rng.Next(), &ls.wi, &pdf);
        const Vec3 wi_l = frame.ToLocal(ls.wi);
        if (pdf > 0 && SidesAgree(wo, ls.wi, hit.ng, wo_l.z, wi_l.z)) {
          Vec3 c = beta * bsdf.Eval(ctx, wo_l, wi_l);
          if (!IsBlack(beta_caustic) && map->CoversEnvironment(ls.wi))
            c -= beta_caustic * bsdf.Eval(ctx, wo_l, wi_l, caustic_lobes);
          if (!IsBlack(c)) {
            ++counters.shadow_rays;
            if (!scene.ShadowOccluded(hit, ls)) add(c * scene.EvalEnvironment(ls.wi) / pdf, depth);
          }
        }
      }
    }
    const float u1 = rng.Next(), u2 = rng.Next(), u3 = rng.Next();
    const BsdfSample bs = bsdf.Sample(ctx, wo_l, u1, u2, u3);
    if (IsBlack(bs.weight)) break;  // failed sample, or a one-sided surface seen from the back
    const Vec3 wi = frame.ToWorld(bs.wi);
    // A direction on the other side of the geometric surface than the shading frame promised
    // would pass through the surface (or be blocked by it): stop.
    if (!SidesAgree(wo, wi, hit.ng, wo_l.z, bs.wi.z)) break;
    if (map != nullptr) {
      if (bs.IsDelta()) {  // delta lobes are the map's; a mask's pass-through is no scattering
        beta_caustic *= bs.weight;
        beta_caustic_next =
            bs.lobe == kNullTransmission ? beta_caustic_next * bs.weight : beta_caustic;
      } else {
        const float inv_pdf = bs.pdf > 0 ? 1.0f / bs.pdf : 0.0f;
        beta_caustic_next = beta_caustic * bsdf.Eval(ctx, wo_l, bs.wi, caustic_lobes) * inv_pdf;
        beta_caustic =
            beta_caustic_next + beta * bsdf.Eval(ctx, wo_l, bs.wi, kDiffuseLobe) * inv_pdf;
      }
    }
    beta *= bs.weight;
    if (bs.lobe == kNullTransmission) {  // passed through a mask: not a scattering vertex
      first = was_first;
      ray = Scene::SpawnRay(hit.p, hit.ng, hit.error_scale, wi);
      continue;
    }
    eta_scale *= bs.eta * bs.eta;
    prev_pdf = bs.IsDelta() ? 0.0f : bs.pdf;
    sun_sampled = sun != nullptr && bsdf.HasSmooth() && !bs.IsDelta();
    if (IsBlack(beta)) break;
    if (depth >= settings.rr_depth) {
      const float q = std::min(MaxComponent(beta) * eta_scale, 0.95f);
      if (rng.Next() >= q) break;
      beta /= q;
      beta_caustic /= q;
      beta_caustic_next /= q;
    }
    prev_p = hit.p;
    prev_n = n_select;
    ray = Scene::SpawnRay(hit.p, hit.ng, hit.error_scale, wi);
    ++counters.bounce_rays;
  }
  return L;
}

}  // namespace irfarm

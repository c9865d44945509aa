// IrrcacheIntegrator::CacheError, the cross-validation --target-error reads its cache's error
// from, against the cache's actual error at the same points, with the truth taken from records of
// many rays: a floor under a uniform sky with a black panel hung above it, where the cache's error
// is mostly interpolation across the panel's shadow. (Where a record's error is its noise alone and
// its hemisphere holds a sharp structure, the variance CacheError takes from the fresh record's two
// checkerboard halves is overstated and the estimate reads low: a dim sky with one bright window at
// 512 rays read 3.2e-4 against a truth of 5.0e-4. An unbiased variance from two independent records
// was tried and not kept: docs/bench/target-check-variance-2026-12-04/.)
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "cache/irradiance_cache.h"
#include "render/irrcache_integrator.h"
#include "render/render_counters.h"
#include "render/renderer.h"
#include "render/sampling.h"
#include "render/scene_loader.h"
#include "tests/render/render_test_util.h"

namespace irfarm {
namespace {

constexpr char kPanelXml[] = R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="60"/>
    <transform name="to_world"><lookat origin="0, 3, -3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="48"/></film>
  </sensor>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="4"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><rotate x="1" angle="90"/><scale value="0.6"/><translate y="0.4"/></transform>
    <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
  </shape>
</scene>
)";

struct Checked {
  double estimate = 0, truth = 0;  // means over the checks
  double se = 0;                   // standard error of the mean of (estimate - truth)
  int checks = 0;
};

// Fills a cache of `rays`-ray records at every pixel centre, then checks it at `n` random points:
// CacheError's figure against ((w (E_interp - E_true))^2 / ((w E_interp)^2 + 0.01)), averaged over
// channels as CacheError averages, with E_true from a record of kTruthRays rays at the same point.
Checked CheckPanelCache(int rays, int n) {
  constexpr int kTruthRays = 2048;
  LoadedScene built =
      BuildLoaded(LoadSceneString(kPanelXml, ::testing::TempDir() + "/panel.xml", {}));
  const Scene& scene = *built.scene;
  IrrcacheSettings settings;  // one cache level: the records' rays are path traced
  settings.accuracy = 0.05f;
  settings.record_rays = rays;
  CacheSettings cs;  // no neighbour clamping: the records' radii as each record made them
  cs.bounds = scene.bounds();
  cs.max_accuracy = settings.accuracy * std::max(settings.lookup_factor, settings.relaxed_factor);
  IrradianceCache cache(cs);
  const IrrcacheIntegrator integrator(scene, &cache, settings);
  IrrcacheSettings truth_settings = settings;
  truth_settings.record_rays = kTruthRays;
  const IrrcacheIntegrator truth(scene, nullptr, truth_settings);  // ComputeRecord only

  const Camera& cam = scene.camera();
  RenderCounters counters;
  Rng rng(7, 1);
  for (int y = 0; y < cam.height(); ++y)
    for (int x = 0; x < cam.width(); ++x)
      integrator.Prime(Ray{cam.origin(), cam.Direction(float(x) + 0.5f, float(y) + 0.5f), INFINITY},
                       rng, counters);

  const double w = 0.5 / kPi;  // the floor's albedo / pi (the panel's is 0: no error there)
  double sum_e = 0, sum_t = 0, sum_d = 0, sum_d2 = 0;
  Checked out;
  for (int i = 0; i < n; ++i) {
    const Ray ray{cam.origin(),
                  cam.Direction(rng.Next() * float(cam.width()), rng.Next() * float(cam.height())),
                  INFINITY};
    double e = 0, noise = 0;
    if (!integrator.CacheError(ray, rng, counters, &e, &noise)) continue;
    SurfaceHit hit;
    EXPECT_TRUE(scene.Intersect(ray, &hit));
    const Vec3 nf = Dot(hit.ns, ray.dir) < 0 ? hit.ns : -hit.ns;
    Vec3 interp;
    LookupInfo info;
    EXPECT_TRUE(integrator.CachedIrradiance(hit.p, nf, 0, 0, 0, nullptr, &interp, &info));
    const Vec3 exact = truth.ComputeRecord(hit, nf, 0, 0.01f, rng, counters).irradiance;
    const bool floor = hit.p.y < 0.1f;
    double t = 0;
    for (int c = 0; c < 3 && floor; ++c) {
      const double v = w * interp[c], d = w * (double(interp[c]) - exact[c]);
      t += d * d / (v * v + 0.01) / 3;
    }
    sum_e += e;
    sum_t += t;
    sum_d += e - t;
    sum_d2 += (e - t) * (e - t);
    ++out.checks;
  }
  const double m = double(std::max(1, out.checks));
  out.estimate = sum_e / m;
  out.truth = sum_t / m;
  out.se = std::sqrt(std::max(0.0, sum_d2 / m - (sum_d / m) * (sum_d / m)) / m);
  return out;
}

// Over 12000 checks the estimate's mean is within 4 standard errors of the truth's (the standard
// error of the paired difference, measured here), and the truth is far enough above 0 for that
// to mean something. (The fresh record's variance, subtracted, is about 5% of the truth at 32
// rays, 2-4 standard errors: this checks the estimate's scale and weights, not that term.)
TEST(CacheErrorTest, EstimatesTheCachesInterpolationErrorUnderAPanel) {
  for (const int rays : {32, 128}) {
    const Checked c = CheckPanelCache(rays, 12000);
    ASSERT_GT(c.checks, 8000) << rays;
    EXPECT_GT(c.truth, 8 * c.se) << rays << " rays: the truth is within the noise";
    EXPECT_NEAR(c.estimate, c.truth, 4 * c.se)
        << rays << " rays: estimate " << c.estimate << ", truth " << c.truth;
  }
}

}  // namespace
}  // namespace irfarm

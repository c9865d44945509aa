#include "render/cache_check.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "render/render_streams.h"

namespace irfarm {
namespace {

// Mean over random pixels of IrrcacheIntegrator::CacheError, clamped at 0: batches of
// `checks` until the mean's standard error is within kCheckPrecision of it, or
// kCheckBatches batches (at most kMostChecks checks). The error a cache makes is concentrated in
// few places (edges of indirect shadows, light through gaps), and one batch of 256 often saw too
// few of them: on thin-panels at E = 4e-3 one batch estimated the cache's error at 1.6e-3, 16
// batches at 2.2e-3, against 2.3e-3 measured at 64 spp against the reference.
constexpr double kCheckPrecision = 0.1;
// Two cache levels: the check records take a quarter of the rays (on veach-ajar the checks of
// full records were two thirds of the refinement's time; a quarter gave the same estimates,
// 1.65e-3 against 1.78e-3, in half the time). Their variance is subtracted all the same.
constexpr float kTwoLevelCheckFraction = 0.25f;
// Two cache levels: the fresh check record looks up the same second-level cache as the records it
// checks, so the cross-validation does not see the second level's error (it is in both). Forced
// to two levels at E = 4e-3, the cache's measured error (relMSE against the reference, less the
// reference's own error and the sampling estimate) against its checked estimate: cornell-box
// 1.6x, sunlit-room 1.9x, thin-panels 1.75x, room-a 1.55x, room-c 1.0x, specular 1.3x, room-d
// 1.6x, room-b 1.1x, veach-ajar 1.95x (at E = 1e-3, where the sampling estimate's own noise weighs
// more: 0.7x to 2.1x). The checked estimate is scaled by the middle of those.
constexpr double kTwoLevelCheckBias = 1.5;
constexpr int kCheckBatches = 16;
constexpr size_t kMostChecks = 8192;

}  // namespace

CacheErrorEstimate EstimateCacheError(const IrrcacheIntegrator& integrator, int levels,
                                      const Camera& cam, uint64_t seed, uint64_t iteration,
                                      int checks, const PixelRect& rect, tbb::task_arena& arena,
                                      tbb::enumerable_thread_specific<RenderCounters>& counters,
                                      float other_factor) {
  const float fraction = levels > 1 ? kTwoLevelCheckFraction : 1.0f;
  // One batch's values; the running sums carry the batches before it.
  std::vector<double> errors(size_t(checks), 0), noises(size_t(checks), 0);
  std::vector<double> other_errors(size_t(checks), 0), other_noises(size_t(checks), 0);
  std::vector<uint8_t> ok(size_t(checks), 0);
  double sum = 0, sum_sq = 0, noise_sum = 0, other_sum = 0, other_noise_sum = 0;
  size_t total = 0;
  int n_ok = 0;
  for (int batch = 0; batch < kCheckBatches; ++batch) {
    arena.execute([&] {
      tbb::parallel_for(0, checks, [&](int j) {
        Rng rng(HashCombine(seed, uint64_t(total) + uint64_t(j)),
                kStreamCacheCheck + 16 * iteration);
        const float x = float(rect.x0) + rng.Next() * float(rect.width());
        const float y = float(rect.y0) + rng.Next() * float(rect.height());
        const Ray ray = cam.PinholeRay(cam.Direction(x, y));
        double e = 0, nz = 0, oe = 0, onz = 0;
        ok[size_t(j)] = integrator.CacheError(ray, rng, counters.local(), &e, &nz, fraction,
                                              other_factor, &oe, &onz);
        errors[size_t(j)] = e;
        noises[size_t(j)] = nz;
        other_errors[size_t(j)] = oe;
        other_noises[size_t(j)] = onz;
      });
    });
    for (size_t j = 0; j < size_t(checks); ++j) {
      sum += errors[j];
      sum_sq += errors[j] * errors[j];
      noise_sum += noises[j];
      other_sum += other_errors[j];
      other_noise_sum += other_noises[j];
      n_ok += ok[j];
    }
    total += size_t(checks);
    const double n = double(total);
    const double mean = sum / n;
    const double se = std::sqrt(std::max(0.0, sum_sq / n - mean * mean) / n);
    if ((mean > 0 && se <= kCheckPrecision * mean) || total >= kMostChecks) break;
  }
  // Pixels with nothing to check (sky, lights, black) have no cache error: they count as 0.
  CacheErrorEstimate out;
  if (n_ok == 0) return out;
  const double bias = levels > 1 ? kTwoLevelCheckBias : 1.0;
  out.error = bias * std::max(0.0, sum / double(total));
  out.noise = std::min(out.error, noise_sum / double(total));
  out.other_error = bias * std::max(0.0, other_sum / double(total));
  out.other_noise = std::min(out.other_error, other_noise_sum / double(total));
  return out;
}

}  // namespace irfarm

#include "render/overture.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <numeric>

#include "render/progress.h"
#include "render/render_streams.h"

namespace irfarm {

void RunOverture(const Camera& cam, const IrrcacheIntegrator& integrator, const PixelRect& rect,
                 uint64_t seed, uint64_t iteration, int threads, bool tty, tbb::task_arena& arena,
                 tbb::enumerable_thread_specific<RenderCounters>& counters,
                 std::vector<uint8_t>* marks, const std::atomic<bool>* cancel) {
  const int w = cam.width();
  const int rw = rect.width(), rh = rect.height();
  // Coarse-to-fine: pixel centres on grids of stride 32, 16, ..., 1. Early passes spread records
  // over the image; later ones only fill what is still uncovered. The rows of all passes form
  // one sequence (pass by pass) that the threads take in order from a shared counter, with no
  // barrier between passes: the coarse passes have a few rows of expensive pixels (most compute
  // a record), and waiting for the last of them at every pass end left a core idle. Within a
  // pass, consecutive rows of the sequence are ~0.62 of the pass apart (golden-ratio stride), so
  // threads work far from each other and rarely compute two records for one spot at once.
  struct Pass {
    int stride, gw, gh, step;  // step: coprime with gh, so r -> r * step mod gh permutes rows
    int begin;                 // index of the pass's first row in the sequence
  };
  std::vector<Pass> passes;
  int total = 0;
  for (int stride = 32; stride >= 1; stride /= 2) {
    const int gw = (rw + stride - 1) / stride, gh = (rh + stride - 1) / stride;
    int step = std::max(1, int(0.618 * gh));
    while (std::gcd(step, gh) != 1) ++step;
    passes.push_back(Pass{stride, gw, gh, step, total});
    total += gh;
  }
  std::atomic<int> next{0};
  Progress progress(tty, total, "overture");
  arena.execute([&] {
    tbb::parallel_for(0, threads, [&](int) {
      RenderCounters& c = counters.local();
      for (int i; (i = next.fetch_add(1, std::memory_order_relaxed)) < total;) {
        if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) break;
        int p = int(passes.size()) - 1;
        while (passes[p].begin > i) --p;
        const Pass& pass = passes[p];
        const int gy = int(int64_t(i - pass.begin) * pass.step % pass.gh);
        const int y = rect.y0 + std::min(rh - 1, gy * pass.stride + pass.stride / 2);
        for (int gx = 0; gx < pass.gw; ++gx) {
          const int x = rect.x0 + std::min(rw - 1, gx * pass.stride + pass.stride / 2);
          Rng rng(HashCombine(seed, uint64_t(y) * w + x),
                  kStreamOverture + 8 * uint64_t(pass.stride) + 1024 * iteration);
          const Ray ray = cam.PinholeRay(cam.Direction(x + 0.5f, y + 0.5f));
          ++c.camera_rays;
          if (integrator.Prime(ray, rng, c) && !marks->empty())
            (*marks)[size_t(y - rect.y0) * rw + (x - rect.x0)] = 1;
        }
        progress.Tick();
      }
    });
  });
}

}  // namespace irfarm

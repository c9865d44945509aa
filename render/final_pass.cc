#include "render/final_pass.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "render/firefly_filter.h"
#include "render/path_tracer.h"
#include "render/pixel_sampler.h"
#include "render/progress.h"
#include "render/render_streams.h"
#include "render/sample_film.h"

namespace irfarm {
namespace {

// Per-pixel random streams and sample points of the final pass, kept across adaptive rounds.
struct PixelStreams {
  PixelStreams(uint64_t seed, int spp, int light_samples)
      : rng(seed, kStreamFinal), film(spp, rng), lights(spp * light_samples, rng) {}
  Rng rng;
  PixelSampler film, lights;
};

}  // namespace

std::vector<Tile> MakeTiles(const PixelRect& r, int size) {
  std::vector<Tile> tiles;
  for (int y = r.y0; y < r.y1; y += size)
    for (int x = r.x0; x < r.x1; x += size)
      tiles.push_back(Tile{x, y, std::min(x + size, r.x1), std::min(y + size, r.y1)});
  return tiles;
}

PathSettings PathIntegratorSettings(const Scene& scene, const RenderSettings& settings) {
  PathSettings path = settings.irrcache.path;
  if (settings.irrcache.direct_sun && !scene.environment_sun().empty())
    path.direct_sun = &scene.environment_sun();
  path.coarse_light_tree = true;
  return path;
}

void FinalPass(const Scene& scene, const RenderSettings& settings,
               const IrrcacheIntegrator& integrator, const PixelRect& rect, bool tty,
               tbb::task_arena& arena, tbb::enumerable_thread_specific<RenderCounters>& counters,
               std::vector<uint8_t>* marks, RenderOutput* out,
               std::chrono::steady_clock::time_point start_time) {
  const Camera& cam = scene.camera();
  const PixelFilter& filter = cam.filter();
  const int w = cam.width(), h = cam.height();
  const int rw = rect.width(), rh = rect.height();
  const size_t npix = size_t(rw) * rh;
  const bool irrcache = settings.integrator == "irrcache";
  const int light_samples = std::max(1, settings.irrcache.light_samples);
  const int spp = std::max(1, settings.spp);
  const bool adaptive = settings.adaptive && spp > 2;
  // Without a target error the adaptive samples have a budget, spp per pixel of the rect on
  // average; with one, they go on until the estimate reaches it. One pixel may take up to
  // max_spp.
  const bool budgeted = adaptive && !(settings.target_error > 0);
  // (At most 2^30, so that doubling a pixel's samples cannot overflow.)
  const int64_t most = settings.max_spp > 0 ? settings.max_spp : int64_t(kMaxSppFactor) * spp;
  const int max_spp = adaptive ? int(std::clamp<int64_t>(most, spp, 1 << 30)) : spp;
  const int min_spp = adaptive ? std::clamp(settings.min_spp, 2, spp) : spp;
  const double goal = settings.target_error > 0 ? settings.target_error : settings.sampling_error;
  const PathSettings path = PathIntegratorSettings(scene, settings);

  // The pixels whose samples reach `rect` (src), and where a pixel of each is.
  const int g = settings.splat ? filter.SplatReach() : 0;
  const PixelRect src{std::max(0, rect.x0 - g), std::max(0, rect.y0 - g), std::min(w, rect.x1 + g),
                      std::min(h, rect.y1 + g)};
  const int sw = src.width();
  const size_t nsrc = size_t(sw) * src.height();
  const auto src_index = [&](size_t p) {  // pixel p of rect -> its index in src
    return size_t(int(p / size_t(rw)) + rect.y0 - src.y0) * sw +
           size_t(int(p % size_t(rw)) + rect.x0 - src.x0);
  };

  std::vector<PixelStreams> streams;
  streams.reserve(nsrc);
  for (size_t q = 0; q < nsrc; ++q) {
    const int x = src.x0 + int(q % size_t(sw)), y = src.y0 + int(q / size_t(sw));
    streams.emplace_back(HashCombine(settings.seed, uint64_t(y) * w + x), max_spp, light_samples);
  }
  std::vector<int> taken(nsrc, 0);  // samples each pixel of src has had
  // Rays traced and cache queries those samples took, the records they made left out (a record
  // is made once, not per sample): the cost of a pixel's next samples for the adaptive rounds.
  std::vector<double> work(nsrc, 0);
  const auto sample_work = [](const RenderCounters& c) { return double(c.Work() - c.record_work); };
  // Pixel q of src's work per sample so far (at least 1).
  const auto work_per_sample = [&](size_t q) {
    return std::max(1.0, work[q] / std::max(1, taken[q]));
  };
  SampleFilm film(npix, irrcache ? integrator.ratio_slots() : 0);
  std::vector<PixelAovSum> aov_sums(settings.aovs ? npix : 0);

  // Samples [from, to) of pixel q of src; `reuse` is the calling thread's (see PixelReuse).
  // `splat`: the first round's samples with g > 0 (see above); otherwise the samples stay in
  // their pixel, which must then be in rect.
  const float splat_weight = g > 0 ? float(filter.SplatSampleWeight()) : 1.0f;
  auto render_pixel = [&](size_t q, int from, int to, bool splat, RenderCounters& c,
                          PixelReuse* reuse) {
    const int x = src.x0 + int(q % size_t(sw)), y = src.y0 + int(q / size_t(sw));
    const bool inside = x >= rect.x0 && x < rect.x1 && y >= rect.y0 && y < rect.y1;
    const size_t own = inside ? size_t(y - rect.y0) * rw + size_t(x - rect.x0) : 0;
    splat = splat && g > 0;
    PixelStreams& ps = streams[q];
    const double work_before = sample_work(c);
    bool made = false;
    SampleAov sample_aov;
    SampleAov* aov = settings.aovs && inside ? &sample_aov : nullptr;
    // Splat weights along each axis: offsets -g..g from (x, y).
    std::array<float, 2 * PixelFilter::kMaxSplatReach + 1> wx{}, wy{};
    // The cancel flag is looked at every 256 samples: a pixel of many samples (a worker's tile
    // of 65536 path samples a pixel) stops within a fraction of a second, not at its end.
    int s = from;
    for (; s < to; ++s) {
      if (((s - from) & 255) == 255 && settings.Cancelled()) break;
      float fu, fv;
      ps.film.Get(s, &fu, &fv);
      const float fx = float(x) + fu, fy = float(y) + fv;
      // thinlens: the lens point from the pixel's stream (a pinhole draws nothing).
      const Ray ray =
          cam.SampleRay(splat ? cam.Direction(fx, fy) : cam.SampleDirection(x, y, fu, fv), ps.rng);
      ++c.camera_rays;
      Vec3 L;
      DirectTerms terms;
      if (irrcache) {
        IrrcacheShade shade;
        shade.reuse = reuse;
        L = integrator.Li(ray, LightStrata{&ps.lights, s * light_samples}, ps.rng, c, &shade,
                          &terms, aov);
        made |= shade.made_record;
      } else {
        L = TracePath(scene, ray, 1, false, path, ps.rng, c, nullptr, aov);
      }
      // A non-finite sample would poison the pixel: it is counted and left out (black), with
      // its direct-light terms (which hold the analytic light apart from L).
      if (!IsFinite(L) || (irrcache && !terms.Finite())) {
        ++c.nonfinite_samples;
        L = Vec3();
        terms = DirectTerms{};
        if (aov) *aov = SampleAov{};
      }
      const DirectTerms* t = irrcache ? &terms : nullptr;
      if (!splat) {
        film.Add(own, s, L, t);
      } else {
        for (int d = -g; d <= g; ++d) {
          wx[size_t(d + g)] = float(filter.Weight(double(fx) - (x + d + 0.5)));
          wy[size_t(d + g)] = float(filter.Weight(double(fy) - (y + d + 0.5)));
        }
        for (int ty = std::max(rect.y0, y - g); ty < std::min(rect.y1, y + g + 1); ++ty) {
          const float wty = wy[size_t(ty - y + g)];
          if (!(wty > 0)) continue;
          for (int tx = std::max(rect.x0, x - g); tx < std::min(rect.x1, x + g + 1); ++tx) {
            const float weight = wty * wx[size_t(tx - x + g)] * splat_weight;
            if (weight > 0)
              film.Add(size_t(ty - rect.y0) * rw + size_t(tx - rect.x0), s, L, t, weight);
          }
        }
      }
      if (aov) aov_sums[own].Add(L, *aov);
    }
    taken[q] = std::max(taken[q], s);
    work[q] += sample_work(c) - work_before;
    if (made && inside && !marks->empty()) (*marks)[own] = 1;
  };

  // Samples [from, to) of every pixel of src, tile by tile (round 0, and adaptive rounds that
  // double every pixel). With splatting, the tiles are the cells of a grid of kSplatTile pixels
  // fixed to the image, run in four phases by the parity of their column and row: a pixel gets
  // at most one tile's samples per phase, added in the tile's pixel order, so its sums are added
  // in the same order whatever the rect, tiles and thread count (path: the tiles of a job
  // assemble into the image one process makes, bit for bit).
  constexpr int kSplatTile = 16;
  static_assert(kSplatTile >= 2 * PixelFilter::kMaxSplatReach);
  std::vector<Tile> tiles;
  std::vector<int> phase_of;
  if (g == 0) {
    tiles = MakeTiles(src, settings.tile_size);
    phase_of.assign(tiles.size(), 0);
  } else {
    for (int gy = src.y0 / kSplatTile; gy * kSplatTile < src.y1; ++gy)
      for (int gx = src.x0 / kSplatTile; gx * kSplatTile < src.x1; ++gx) {
        tiles.push_back(Tile{std::max(src.x0, gx * kSplatTile), std::max(src.y0, gy * kSplatTile),
                             std::min(src.x1, (gx + 1) * kSplatTile),
                             std::min(src.y1, (gy + 1) * kSplatTile)});
        phase_of.push_back(gx % 2 + 2 * (gy % 2));
      }
  }
  const auto render_all = [&](int from, int to, Progress* progress) {
    std::vector<size_t> batch;
    for (int phase = 0; phase < (g > 0 ? 4 : 1); ++phase) {
      batch.clear();
      for (size_t t = 0; t < tiles.size(); ++t)
        if (phase_of[t] == phase) batch.push_back(t);
      arena.execute([&] {
        tbb::parallel_for(size_t(0), batch.size(), [&](size_t i) {
          if (settings.Cancelled()) return;
          const Tile& tile = tiles[batch[i]];
          RenderCounters& c = counters.local();
          PixelReuse reuse;
          for (int y = tile.y0; y < tile.y1 && !settings.Cancelled(); ++y)
            for (int x = tile.x0; x < tile.x1 && !settings.Cancelled(); ++x)
              render_pixel(size_t(y - src.y0) * sw + size_t(x - src.x0), from, to, true, c, &reuse);
          if (progress) progress->Tick();
        });
      });
    }
  };
  {
    Progress progress(tty, int(tiles.size()), "render");
    render_all(0, min_spp, &progress);
  }
  // While every pixel of src has had the same samples, a round that doubles them all keeps the
  // sample density even and splats too.
  bool even = true;

  // Adaptive rounds.
  std::vector<double> err(npix), smooth(npix), share(npix), cost_per_sample(npix);
  double estimate = 0;
  int rounds = 0;
  for (;;) {
    double sum = 0;
    for (size_t p = 0; p < npix; ++p) sum += err[p] = film.RelativeError(p);
    estimate = sum / double(npix);
    if (!adaptive || estimate <= goal || settings.Cancelled()) break;
    if (settings.time_limit > 0 &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count() >=
            settings.time_limit)
      break;
    // Each pixel's error is taken as the mean estimate over its 8 neighbours, not its own: one
    // pixel's two halves can agree by chance, its neighbours rarely all do; and a pixel whose
    // own samples decide how many it gets is biased (one that caught a rare bright path gets
    // more, which dilute it; one that missed it stops at 0): adaptive path on specular's
    // caustics was 0.9% dark with its own error counted. The budget is the work spp samples of
    // every pixel would take at each pixel's measured work per sample (a sample through glass or
    // a glossy chain costs several of one on a diffuse wall).
    double used = 0, own = 0;
    for (int y = 0; y < rh; ++y)
      for (int x = 0; x < rw; ++x) {
        const size_t p = size_t(y) * rw + x;
        const size_t q = src_index(p);
        cost_per_sample[p] = work_per_sample(q);
        used += taken[q] * cost_per_sample[p];
        own += spp * cost_per_sample[p];
        double acc = 0;
        int n = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if ((dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= rw || yy >= rh) continue;
            acc += err[size_t(yy) * rw + xx];
            ++n;
          }
        smooth[p] = n > 0 ? acc / n : err[p];  // a 1 x 1 rect has no neighbours
      }
    // With a budget, each pixel's share of it: for a fixed work sum c_p n_p the sum of the
    // pixels' errors v_p / n_p (v_p: error per sample, c_p: work per sample) is least at n_p
    // proportional to sqrt(v_p / c_p) (Neyman allocation), here within [the samples it has,
    // max_spp]; lambda is found by bisection. A pixel is a candidate when its share is at least
    // 1.5x what it has (doubling is the nearest step).
    const double budget = own + std::min(own, std::max(0.0, settings.budget_carry));
    const double left = budget - used;
    if (budgeted && left < 1) break;
    if (budgeted) {
      const auto planned = [&](double lambda) {
        double total = 0;
        for (size_t p = 0; p < npix; ++p) {
          const double n = taken[src_index(p)];
          share[p] = std::clamp(lambda * std::sqrt(smooth[p] * n / cost_per_sample[p]), n,
                                double(max_spp));
          total += share[p] * cost_per_sample[p];
        }
        return total;
      };
      double lo = 0, hi = 1;
      while (planned(hi) < budget && hi < 1e30) hi *= 2;
      for (int i = 0; i < 60 && hi > 1.0001 * lo; ++i) {
        const double mid = lo > 0 ? std::sqrt(lo * hi) : 0.5 * hi;
        (planned(mid) < budget ? lo : hi) = mid;
      }
      planned(lo);
    }
    std::vector<size_t> candidates;
    for (size_t p = 0; p < npix; ++p) {
      const int n = taken[src_index(p)];
      if (n < max_spp && (!budgeted || share[p] >= 1.5 * n)) candidates.push_back(p);
    }
    if (candidates.empty()) break;
    // Doubling a pixel's samples halves its error: take the pixels where that removes the most
    // error per unit of work until it covers the excess over the goal (at least 1/16 of the
    // candidates, so every round does real work), or the budget is spent.
    const auto per_work = [&](size_t p) {
      return smooth[p] / (taken[src_index(p)] * cost_per_sample[p]);
    };
    std::sort(candidates.begin(), candidates.end(),
              [&](size_t a, size_t b) { return per_work(a) > per_work(b); });
    const double excess = (estimate - goal) * double(npix);
    double gain = 0, cost = 0;
    size_t k = 0;
    const size_t at_least = std::max<size_t>(1, candidates.size() / 16);
    while (k < candidates.size() && (gain < excess || k < at_least)) {
      const int n = taken[src_index(candidates[k])];
      const double c = (std::min(2 * n, max_spp) - n) * cost_per_sample[candidates[k]];
      if (budgeted && cost + c > 1.000001 * left) break;
      cost += c;
      gain += 0.5 * smooth[candidates[k]];
      ++k;
    }
    if (k == 0) break;
    candidates.resize(k);
    if (even && g > 0 && k == npix) {
      const int n = taken[0];
      render_all(n, std::min(2 * n, max_spp), nullptr);
      ++rounds;
      continue;
    }
    even = false;
    std::sort(candidates.begin(), candidates.end());
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, candidates.size(), 16),
                        [&](const tbb::blocked_range<size_t>& r) {
                          if (settings.Cancelled()) return;
                          RenderCounters& c = counters.local();
                          PixelReuse reuse;
                          for (size_t i = r.begin(); i < r.end(); ++i) {
                            const size_t q = src_index(candidates[i]);
                            const int n = taken[q];
                            render_pixel(q, n, std::min(2 * n, max_spp), false, c, &reuse);
                          }
                        });
    });
    ++rounds;
  }

  RenderStats& st = out->stats;
  st.adaptive_rounds = rounds;
  if (budgeted) {  // the budget as the rounds counted it, at the pixels' final work per sample
    double own = 0, used = 0;
    for (size_t p = 0; p < npix; ++p) {
      const size_t q = src_index(p);
      const double c = work_per_sample(q);
      own += spp * c;
      used += taken[q] * c;
    }
    const double carry = std::max(0.0, settings.budget_carry);
    st.budget_left = std::max(0.0, own + carry - used);
  }
  st.estimated_sampling_relmse = estimate;
  long early = 0;
  double spp_sum = 0;
  st.spp_min = max_spp;
  st.spp_max = 0;
  if (settings.aovs) out->aovs = AovImages(rw, rh);
  for (size_t p = 0; p < npix; ++p) {
    out->image.pixels[p] = film.Value(p);
    const int n = taken[src_index(p)];
    if (settings.aovs) {
      const int x = int(p % size_t(rw)), y = int(p / size_t(rw));
      out->aovs.Set(x, y, aov_sums[p], n);
      // The rectangles' ratio estimate (DirectTerms) is formed per pixel: direct light too.
      out->aovs.direct.at(x, y) += out->image.pixels[p] - film.SampleMean(p);
    }
    early += n < spp;
    spp_sum += n;
    st.spp_min = std::min(st.spp_min, n);
    st.spp_max = std::max(st.spp_max, n);
  }
  st.pixels_stopped_early = early;
  if (settings.keep_peaks || settings.firefly_filter) {
    std::vector<Vec3> peak(npix);
    for (size_t p = 0; p < npix; ++p) peak[p] = FireflyPeak(film.Peak(p), taken[src_index(p)]);
    if (settings.keep_peaks) {  // whoever assembles the image spreads them
      out->peak = Image(rw, rh);
      out->peak.pixels = std::move(peak);
    } else {
      // The AOVs whose sum is the image (emission is part of direct) move with it.
      std::vector<Image*> layers;
      if (settings.aovs) layers = {&out->aovs.direct, &out->aovs.indirect, &out->aovs.emission};
      st.fireflies_spread = SpreadFireflies(out->image, peak, layers);
    }
  }
  st.spp_mean = spp_sum / double(std::max<size_t>(1, npix));
  if (settings.sample_map) {
    out->sample_map = Image(rw, rh);
    const float scale = 1 / std::log2(float(max_spp) + 1);
    for (size_t p = 0; p < npix; ++p) {
      const float t = std::log2(float(taken[src_index(p)]) + 1) * scale;
      // Dark blue (few samples) through red to yellow-white (the most).
      out->sample_map.pixels[p] =
          Vec3(std::min(1.0f, 2 * t), std::max(0.0f, 2 * t - 1), std::max(0.0f, 0.5f - t));
    }
  }
}

}  // namespace irfarm

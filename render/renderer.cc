#include "render/renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <thread>

#include "absl/strings/numbers.h"
#include "render/path_tracer.h"

namespace irfarm {
namespace {

// Distinct random streams for the passes that touch a pixel.
enum : uint64_t { kStreamFinal = 1, kStreamOverture = 2 };

class Progress {
 public:
  Progress(bool enabled, int total, const char* what)
      : enabled_(enabled), total_(total), what_(what), start_(Now()) {}
  ~Progress() {
    if (enabled_) std::fprintf(stderr, "\n");
  }
  void Tick() {
    const int done = ++done_;
    if (!enabled_) return;
    const double now = Now();
    double last = last_.load();
    if (done < total_ && now - last < 0.2) return;
    if (!last_.compare_exchange_strong(last, now)) return;
    const double el = now - start_, rate = done / std::max(el, 1e-9);
    std::fprintf(stderr, "\r%s: tiles %d/%d  %.1f tiles/s  ETA %.0fs   ", what_, done, total_, rate,
                 (total_ - done) / std::max(rate, 1e-9));
    std::fflush(stderr);
  }

 private:
  static double Now() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
  bool enabled_;
  int total_;
  const char* what_;
  double start_;
  std::atomic<int> done_{0};
  std::atomic<double> last_{0};
};

struct Tile {
  int x0, y0, x1, y1;
};

std::vector<Tile> MakeTiles(const PixelRect& r, int size) {
  std::vector<Tile> tiles;
  for (int y = r.y0; y < r.y1; y += size)
    for (int x = r.x0; x < r.x1; x += size)
      tiles.push_back(Tile{x, y, std::min(x + size, r.x1), std::min(y + size, r.y1)});
  return tiles;
}

}  // namespace

absl::StatusOr<RenderSettings> SettingsForScene(const SceneDesc& desc,
                                                const std::string& integrator) {
  RenderSettings s;
  s.integrator = integrator;
  s.irrcache.path.max_depth = desc.integrator.max_depth;
  s.irrcache.path.rr_depth = desc.integrator.rr_depth;
  IrrcacheSettings& ic = s.irrcache;
  double spp = 64;
  if (desc.integrator.type == "irrcache") {
    static constexpr const char* kKnown[] = {"accuracy",       "record_rays",    "light_samples",
                                             "min_spacing_px", "max_spacing_px", "spp"};
    std::map<std::string, double> values;
    for (const auto& [name, text] : desc.integrator.params) {
      bool found = false;
      for (const char* k : kKnown) found |= name == k;
      double v = 0;
      if (!found)
        return absl::InvalidArgumentError(desc.integrator.loc.ToString() +
                                          ": unknown irrcache parameter '" + name +
                                          "' (supported: accuracy, record_rays, light_samples, "
                                          "min_spacing_px, max_spacing_px, spp)");
      if (!absl::SimpleAtod(text, &v) || !std::isfinite(v) || v <= 0 ||
          (name == "accuracy" && v > 1))
        return absl::InvalidArgumentError(
            desc.integrator.loc.ToString() + ": irrcache parameter '" + name +
            "' must be a positive number" + (name == "accuracy" ? " <= 1" : "") + ", got '" + text +
            "'");
      values[name] = v;
    }
    if (values.count("accuracy")) ic.accuracy = float(values["accuracy"]);
    if (values.count("record_rays")) ic.record_rays = int(values["record_rays"]);
    if (values.count("light_samples")) ic.light_samples = int(values["light_samples"]);
    if (values.count("min_spacing_px")) ic.min_spacing_px = float(values["min_spacing_px"]);
    if (values.count("max_spacing_px")) ic.max_spacing_px = float(values["max_spacing_px"]);
    if (values.count("spp")) spp = values["spp"];
  }
  s.spp = integrator == "path" ? desc.camera.spp : std::max(1, int(spp));
  return s;
}

CacheSettings CacheSettingsFor(const Scene& scene, const RenderSettings& settings) {
  CacheSettings cs;
  cs.bounds = scene.bounds();
  cs.max_accuracy =
      std::min(1.0f, settings.irrcache.accuracy * std::max(1.0f, settings.irrcache.relaxed_factor));
  return cs;
}

RenderOutput Render(const Scene& scene, const RenderSettings& settings, IrradianceCache* cache) {
  const Camera& cam = scene.camera();
  return RenderRect(scene, settings, cache, PixelRect{0, 0, cam.width(), cam.height()});
}

RenderOutput RenderRect(const Scene& scene, const RenderSettings& settings, IrradianceCache* cache,
                        const PixelRect& rect) {
  RenderOutput out;
  const Camera& cam = scene.camera();
  const int w = cam.width();
  const int rw = rect.width(), rh = rect.height();
  const bool irrcache = settings.integrator == "irrcache";
  const int threads = settings.threads > 0 ? settings.threads
                                           : int(std::max(1u, std::thread::hardware_concurrency()));
  std::unique_ptr<IrradianceCache> own_cache;
  if (irrcache && !cache) {
    own_cache = std::make_unique<IrradianceCache>(CacheSettingsFor(scene, settings));
    cache = own_cache.get();
  }
  IrrcacheIntegrator integrator(scene, cache, settings.irrcache);
  out.image = Image(rw, rh);
  std::vector<uint8_t> marks(settings.record_map ? size_t(rw) * rh : 0);
  tbb::enumerable_thread_specific<RenderCounters> counters;
  tbb::task_arena arena(threads);
  const std::vector<Tile> tiles = MakeTiles(rect, settings.tile_size);
  const PathSettings& path = settings.irrcache.path;
  const bool tty = settings.progress && isatty(STDERR_FILENO);
  const int light_samples = std::max(1, settings.irrcache.light_samples);

  if (irrcache && settings.overture) {
    PhaseTimer timer("overture");
    // Coarse-to-fine: pixel centres on grids of stride 32, 16, ..., 1. Early passes spread records
    // over the image; later ones only fill what is still uncovered.
    for (int stride = 32; stride >= 1; stride /= 2) {
      const int gw = (rw + stride - 1) / stride, gh = (rh + stride - 1) / stride;
      Progress progress(tty && stride == 1, gh, "overture");
      arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<int>(0, gh), [&](const tbb::blocked_range<int>& r) {
          RenderCounters& c = counters.local();
          for (int gy = r.begin(); gy < r.end(); ++gy) {
            for (int gx = 0; gx < gw; ++gx) {
              const int x = rect.x0 + std::min(rw - 1, gx * stride + stride / 2);
              const int y = rect.y0 + std::min(rh - 1, gy * stride + stride / 2);
              Rng rng(HashCombine(settings.seed, uint64_t(y) * w + x),
                      kStreamOverture + 8 * uint64_t(stride));
              const Ray ray{cam.origin(), cam.Direction(x + 0.5f, y + 0.5f), INFINITY};
              ++c.camera_rays;
              if (integrator.Prime(ray, rng, c) && !marks.empty())
                marks[size_t(y - rect.y0) * rw + (x - rect.x0)] = 1;
            }
            progress.Tick();
          }
        });
      });
    }
    out.stats.phases.push_back(timer.Stop());
    for (const RenderCounters& c : counters) out.stats.records_overture += c.records_computed;
  }

  {
    PhaseTimer timer("render");
    Progress progress(tty, int(tiles.size()), "render");
    arena.execute([&] {
      tbb::parallel_for(size_t(0), tiles.size(), [&](size_t ti) {
        const Tile& tile = tiles[ti];
        RenderCounters& c = counters.local();
        for (int y = tile.y0; y < tile.y1; ++y)
          for (int x = tile.x0; x < tile.x1; ++x) {
            Rng rng(HashCombine(settings.seed, uint64_t(y) * w + x), kStreamFinal);
            // Even and odd samples are kept apart (two interleaved half-images) so that their
            // difference estimates the pixel's error; the pixel is their joint estimate.
            Vec3 sum[2];
            DirectTerms terms[2];
            bool made = false;
            const PixelSampler film(settings.spp, rng);
            const PixelSampler lights(settings.spp * light_samples, rng);
            for (int s = 0; s < settings.spp; ++s) {
              float fx, fy;
              film.Get(s, &fx, &fy);
              fx += float(x);
              fy += float(y);
              const Ray ray{cam.origin(), cam.Direction(fx, fy), INFINITY};
              ++c.camera_rays;
              Vec3 L;
              if (irrcache) {
                IrrcacheShade shade;
                L = integrator.Li(ray, LightStrata{&lights, s * light_samples}, rng, c, &shade,
                                  &terms[s & 1]);
                made |= shade.made_record;
              } else {
                L = TracePath(scene, ray, 1, false, path, rng, c);
              }
              // A non-finite sample would poison the pixel: it is counted and left out.
              if (IsFinite(L))
                sum[s & 1] += L;
              else
                ++c.nonfinite_samples;
            }
            DirectTerms all = terms[0];
            all.Add(terms[1]);
            out.image.at(x - rect.x0, y - rect.y0) =
                (sum[0] + sum[1] + all.Resolve()) / float(settings.spp);
            if (made && !marks.empty()) marks[size_t(y - rect.y0) * rw + (x - rect.x0)] = 1;
          }
        progress.Tick();
      });
    });
    out.stats.phases.push_back(timer.Stop());
  }

  RenderStats& st = out.stats;
  for (const RenderCounters& c : counters) st.counters.Add(c);
  st.integrator = settings.integrator;
  st.width = rw;
  st.height = rh;
  st.spp = settings.spp;
  st.threads = threads;
  st.seed = settings.seed;
  st.tiles = int(tiles.size());
  st.tile_size = settings.tile_size;
  if (irrcache) {
    st.accuracy = settings.irrcache.accuracy;
    st.record_rays = integrator.strata_theta() * integrator.strata_phi();
    st.strata_theta = integrator.strata_theta();
    st.strata_phi = integrator.strata_phi();
    st.light_samples = settings.irrcache.light_samples;
    st.min_spacing_px = settings.irrcache.min_spacing_px;
    st.max_spacing_px = settings.irrcache.max_spacing_px;
    st.records_in_cache = cache->size();
  }
  double m[3] = {0, 0, 0};
  for (const Vec3& p : out.image.pixels) {
    if (!IsFinite(p)) ++st.nonfinite_pixels;
    for (int k = 0; k < 3; ++k) m[k] += p[k];
  }
  const double n = double(out.image.pixels.size());
  st.mean_rgb = Vec3(float(m[0] / n), float(m[1] / n), float(m[2] / n));
  if (settings.record_map) {
    out.record_map = out.image;
    for (size_t i = 0; i < marks.size(); ++i)
      out.record_map.pixels[i] = marks[i] ? Vec3(1e3f, 0, 0) : out.record_map.pixels[i] * 0.5f;
  }
  return out;
}

}  // namespace irfarm

#include "render/environment_guide.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <tbb/parallel_for.h>

#include "render/sampling.h"
#include "render/scene.h"

namespace irfarm {

namespace {
constexpr float kBinSolidAngle = 4 * kPi / float(EnvironmentGuide::kBins);

uint16_t Quantize(double c) {
  return uint16_t(std::lround(std::clamp(c, 0.0, 1.0) * EnvironmentGuide::kOne));
}

// Where u (in [0, 1)) falls in a run of n cumulative values ending at kOne: the entry, its
// share of the run, and u's place within it (in [0, 1)). False when the entry has no share.
bool Pick(const uint16_t* run, int n, float u, int* index, float* share, float* rest) {
  const float t = u * float(EnvironmentGuide::kOne);
  const uint32_t ti = std::min(uint32_t(t), EnvironmentGuide::kOne - 1);
  const int i = int(std::upper_bound(run, run + n, ti) - run);
  if (i >= n) return false;
  const uint32_t prev = i > 0 ? run[i - 1] : 0;
  const uint32_t width = uint32_t(run[i]) - prev;
  if (width == 0) return false;
  *index = i;
  *share = float(width) / float(EnvironmentGuide::kOne);
  *rest = std::min((t - float(prev)) / float(width), 0x1.fffffep-1f);
  return true;
}

float Share(const uint16_t* run, int i) {
  return float(uint32_t(run[i]) - (i > 0 ? uint32_t(run[i - 1]) : 0u)) /
         float(EnvironmentGuide::kOne);
}

// atan2(y, x) within 1e-5 radians (a minimax polynomial for atan on [0, 1]); std::atan2 was 3%
// of a guided render's time.
float FastAtan2(float y, float x) {
  const float ax = std::fabs(x), ay = std::fabs(y);
  const float hi = std::max(ax, ay), lo = std::min(ax, ay);
  if (!(hi > 0)) return 0;
  const float t = lo / hi, t2 = t * t;
  float a =
      t * (0.99997726f +
           t2 * (-0.33262347f +
                 t2 * (0.19354346f + t2 * (-0.11643287f + t2 * (0.05265332f - t2 * 0.01172120f)))));
  if (ay > ax) a = 0.5f * kPi - a;
  if (x < 0) a = kPi - a;
  return y < 0 ? -a : a;
}
}  // namespace

int EnvironmentGuide::BinOf(const Vec3& wi) {
  const int iz = std::clamp(int((wi.z + 1) * 0.5f * float(kBandsZ)), 0, kBandsZ - 1);
  const float phi = FastAtan2(wi.y, wi.x) + kPi;  // [0, 2 pi]
  const int ip = std::clamp(int(phi * (0.5f * kInvPi) * float(kBandsPhi)), 0, kBandsPhi - 1);
  return iz * kBandsPhi + ip;
}

int EnvironmentGuide::Grid::Key(const Vec3& p) const {
  if (index.empty()) return -1;
  const Vec3 c = (p - lo) / cell;
  const float cf[3] = {c.x, c.y, c.z};
  int ci[3];
  for (int a = 0; a < 3; ++a) {
    if (!(cf[a] >= 0 && cf[a] < float(res[a]))) return -1;  // outside, or NaN
    ci[a] = std::min(int(cf[a]), res[a] - 1);
  }
  return (ci[2] * res[1] + ci[1]) * res[0] + ci[0];
}

int EnvironmentGuide::ClassOf(const Vec3& n) {
  const float a[3] = {std::fabs(n.x), std::fabs(n.y), std::fabs(n.z)};
  const int axis = a[0] >= a[1] && a[0] >= a[2] ? 0 : (a[1] >= a[2] ? 1 : 2);
  const float c = axis == 0 ? n.x : (axis == 1 ? n.y : n.z);
  if (!(c != 0)) return -1;  // zero (or NaN): no normal
  return 2 * axis + (c < 0);
}

int EnvironmentGuide::CellOf(const Vec3& p, const Vec3& n) const {
  const int cls = ClassOf(n);
  if (cls < 0) return -1;
  for (const Grid& grid : levels_) {
    const int key = grid.Key(p);
    if (key < 0) continue;
    const int32_t h = grid.index[size_t(key) * kClasses + size_t(cls)];
    if (h >= 0) return h;
  }
  return -1;
}

EnvironmentGuide EnvironmentGuide::Learn(const Scene& scene) {
  EnvironmentGuide g;
  if (!scene.has_environment()) return g;
  const LightSampler& lights = scene.light_sampler();
  const Camera& camera = scene.camera();
  // Random streams: one per path, one per vertex and round; fixed, so every process (and any
  // thread count) learns the same guide.
  constexpr uint64_t kSeed = 0x243f6a8885a308d3ull;

  // The camera paths' vertices, facing the side their ray came from; traced in parallel, each path
  // into its own slots, then gathered in path order.
  std::vector<SurfaceHit> slots(size_t(kPaths) * kVertices);
  std::vector<int> depth(size_t(kPaths), 0);
  tbb::parallel_for(0, kPaths, [&](int i) {
    Rng rng(kSeed, uint64_t(i));
    const float x = rng.Next() * float(camera.width()), y = rng.Next() * float(camera.height());
    Ray ray = camera.SampleRay(camera.Direction(x, y), rng);
    for (int k = 0; k < kVertices; ++k) {
      SurfaceHit& hit = slots[size_t(i) * kVertices + size_t(k)];
      if (!scene.Intersect(ray, &hit)) break;
      if (Dot(hit.ng, ray.dir) > 0) hit.ng = -hit.ng;
      depth[size_t(i)] = k + 1;
      Vec3 a, b;
      MakeFrame(hit.ng, &a, &b);
      const float u = rng.Next(), v = rng.Next();
      const Vec3 local = CosineHemisphere(u, v);
      ray = Scene::SpawnRay(hit.p, hit.ng, hit.error_scale,
                            a * local.x + b * local.y + hit.ng * local.z);
    }
  });
  std::vector<SurfaceHit> vertices;
  for (int i = 0; i < kPaths; ++i)
    for (int k = 0; k < depth[size_t(i)]; ++k) vertices.push_back(slots[size_t(i) * kVertices + k]);
  if (vertices.empty()) return g;

  Bounds3 box;
  for (const SurfaceHit& h : vertices) box.Extend(h.p);
  const Vec3 d = box.Diagonal();
  const float side = std::max({d.x, d.y, d.z});
  if (!(side > 0) || !std::isfinite(side)) return g;
  const float extent[3] = {d.x, d.y, d.z};
  size_t offset[kLevels + 1] = {0};
  for (int l = 0; l < kLevels; ++l) {
    Grid& grid = g.levels_[l];
    grid.lo = box.lo;
    grid.cell = side / float(kCells[l]) * (1 + 1e-4f);
    for (int a = 0; a < 3; ++a)
      grid.res[a] = std::clamp(int(extent[a] / grid.cell) + 1, 1, kCells[l]);
    offset[l + 1] =
        offset[l] + size_t(grid.res[0]) * size_t(grid.res[1]) * size_t(grid.res[2]) * kClasses;
  }

  struct Acc {
    float weight = 0;  // trilinear-weighted count of unblocked samples
    std::vector<float> bins = std::vector<float>(kBins, 0.0f);
  };
  std::unordered_map<size_t, Acc> acc;
  // One round: kRaysPerVertex samples at each vertex from `sample` (a direction and its density),
  // traced in parallel; then the unblocked ones, in vertex order, splatted into both grids.
  struct Found {
    int bin = -1;
    float weight = 0;      // radiance over density
    float irradiance = 0;  // ... times the cosine at the vertex
  };
  std::vector<Found> found(vertices.size() * kRaysPerVertex);
  const auto round = [&](uint64_t stream, auto&& sample) {
    tbb::parallel_for(size_t(0), vertices.size(), [&](size_t v) {
      const SurfaceHit& h = vertices[v];
      Rng rng(kSeed, stream + v);
      for (int r = 0; r < kRaysPerVertex; ++r) {
        Found& f = found[v * kRaysPerVertex + size_t(r)];
        f = Found();
        LightSample ls;
        if (!sample(h, rng, &ls)) continue;
        if (scene.ShadowOccluded(h, ls)) continue;
        const float w = Luminance(scene.EvalEnvironment(ls.wi)) / ls.pdf;
        if (!(w > 0) || !std::isfinite(w)) continue;
        f.bin = BinOf(ls.wi);
        f.weight = w;
        f.irradiance = w * std::max(0.0f, Dot(ls.wi, h.ng));
      }
    });
    for (size_t v = 0; v < vertices.size(); ++v) {
      const Vec3& p = vertices[v].p;
      const int cls = ClassOf(vertices[v].ng);
      if (cls < 0) continue;
      for (int r = 0; r < kRaysPerVertex; ++r) {
        const Found& f = found[v * kRaysPerVertex + size_t(r)];
        if (f.bin < 0) continue;
        for (int l = 0; l < kLevels; ++l) {
          const Grid& grid = g.levels_[l];
          // Trilinear weights over the 8 cells whose centres surround p.
          const Vec3 c = (p - grid.lo) / grid.cell - Vec3(0.5f, 0.5f, 0.5f);
          const float cf[3] = {c.x, c.y, c.z};
          for (int corner = 0; corner < 8; ++corner) {
            int ci[3];
            float t = 1;
            for (int a = 0; a < 3; ++a) {
              const int i0 = int(std::floor(cf[a]));
              const float fr = cf[a] - float(i0);
              const int up = (corner >> a) & 1;
              ci[a] = std::clamp(i0 + up, 0, grid.res[a] - 1);
              t *= up ? fr : 1 - fr;
            }
            if (!(t > 0)) continue;
            const size_t cell = size_t((ci[2] * grid.res[1] + ci[1]) * grid.res[0] + ci[0]);
            Acc& cell_acc = acc[offset[l] + cell * kClasses + size_t(cls)];
            cell_acc.weight += t;
            cell_acc.bins[size_t(f.bin)] += t * f.weight;
          }
        }
      }
    }
  };
  // The histograms from what acc holds so far.
  const auto finish = [&]() {
    g.cdf_.clear();
    for (int l = 0; l < kLevels; ++l) g.levels_[l].index.assign(offset[l + 1] - offset[l], -1);
    for (const auto& [key, a] : acc) {
      if (a.weight < kMinWeight) continue;
      double total = 0;
      for (float v : a.bins) total += v;
      if (!(total > 0)) continue;
      const size_t base = g.cdf_.size();
      g.cdf_.resize(base + kStride);
      uint16_t* bands = &g.cdf_[base];
      double run = 0;
      for (int iz = 0; iz < kBandsZ; ++iz) {
        const float* row = &a.bins[size_t(iz) * kBandsPhi];
        uint16_t* sectors = &g.cdf_[base + kBandsZ + size_t(iz) * kBandsPhi];
        double band = 0;
        for (int ip = 0; ip < kBandsPhi; ++ip) band += row[ip];
        double within = 0;
        for (int ip = 0; ip < kBandsPhi; ++ip) {
          within += row[ip];
          // An empty band's sectors are never drawn; uniform keeps the run well formed.
          sectors[ip] = Quantize(band > 0 ? within / band : double(ip + 1) / kBandsPhi);
        }
        sectors[kBandsPhi - 1] = kOne;
        run += band;
        bands[iz] = Quantize(run / total);
      }
      bands[kBandsZ - 1] = kOne;
      int l = 0;
      while (key >= offset[l + 1]) ++l;
      g.levels_[l].index[key - offset[l]] = int32_t(base / kStride);
    }
  };

  // Round 1: the unguided sampler. Round 2: LightSampler's mixture with round 1's histograms as
  // its guide (LightSampler::kGuideShare of the samples from them, each weighed by the mixture's
  // density), which finds the openings far more often.
  round(uint64_t(kPaths), [&](const SurfaceHit& h, Rng& rng, LightSample* ls) {
    const float u2 = rng.Next(), u3 = rng.Next();
    return lights.SampleEnvironment(h.p, h.ng, u2, u3, ls, true);
  });
  finish();
  // Guiding costs time: more samples pass, and a ray that leaves the scene crosses all of it. It
  // pays only where the unguided samples mostly hit walls, and where the sky is not a minor light.
  // Measured with the guide everywhere (docs/bench/env-guide-2026-12-05): living-room and rooms
  // lit only through their windows (0.5-2% of round 1's samples passed) gained; scenes open to
  // the sky (materials, principled: 8.4%) lost 12-18% in error x time, and rooms where lamps or a
  // sun outshine the sky (1-2% of the direct light) lost 5-8%.
  long passed = 0;
  for (const Found& f : found) passed += f.bin >= 0;
  if (!(double(passed) < kMaxPassFraction * double(found.size()))) return EnvironmentGuide();
  // The sky's irradiance at the vertices as round 1 measured it, against the local lights'
  // unoccluded estimates (LightSampler::Weight).
  if (lights.num_local() <= LightSampler::kMaxSpatialLights) {
    double env = 0, local = 0;
    for (const Found& f : found) env += f.irradiance;
    env /= kRaysPerVertex;
    for (const SurfaceHit& h : vertices)
      for (int i = 0; i < lights.num_local(); ++i) local += lights.Weight(i, h.p, h.ng);
    if (!(env >= kMinEnvironmentShare * (env + local))) return EnvironmentGuide();
  }
  const EnvironmentGuide first = g;
  round(uint64_t(kPaths) + vertices.size(), [&](const SurfaceHit& h, Rng& rng, LightSample* ls) {
    const float u2 = rng.Next(), u3 = rng.Next();
    return lights.SampleEnvironment(&first, h.p, h.ng, u2, u3, ls, true);
  });
  finish();
  return g;
}

bool EnvironmentGuide::Sample(int cell, float u1, float u2, Vec3* wi, float* pdf) const {
  const uint16_t* bands = &cdf_[size_t(cell) * kStride];
  // u1 picks the band, its place within the band the sector, and its place within that the z.
  int iz = 0, ip = 0;
  float pz = 0, pp = 0, uz = 0, uzz = 0;
  if (!Pick(bands, kBandsZ, u1, &iz, &pz, &uz)) return false;
  if (!Pick(bands + kBandsZ + iz * kBandsPhi, kBandsPhi, uz, &ip, &pp, &uzz)) return false;
  const float z = -1 + 2 * (float(iz) + uzz) / float(kBandsZ);
  const float phi = 2 * kPi * (float(ip) + u2) / float(kBandsPhi) - kPi;
  const float r = std::sqrt(std::max(0.0f, 1 - z * z));
  *wi = Vec3(r * std::cos(phi), r * std::sin(phi), z);
  *pdf = Pdf(cell, *wi);
  return *pdf > 0;
}

float EnvironmentGuide::Pdf(int cell, const Vec3& wi) const {
  const uint16_t* bands = &cdf_[size_t(cell) * kStride];
  const int b = BinOf(wi), iz = b / kBandsPhi, ip = b % kBandsPhi;
  return Share(bands, iz) * Share(bands + kBandsZ + iz * kBandsPhi, ip) / kBinSolidAngle;
}

}  // namespace irfarm

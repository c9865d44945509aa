// Micro-benchmarks (Google Benchmark) of the hot paths: irradiance-cache lookups, Embree ray casts
// (closest hit and occlusion) in the Cornell box, a record's derivatives, Beckmann sampling and a
// mesh lamp's light-tree walk, core/fast_trig.h's atan2 beside libm's, and the walk a worker takes
// its new records with (all records, or since a mark).
// Run: build/bench/bench_micro.
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <memory>
#include <vector>

#include "cache/irradiance_cache.h"
#include "core/fast_trig.h"
#include "render/bsdfs/microfacet.h"
#include "render/irradiance_hessian.h"
#include "render/light_tree.h"
#include "render/pipeline.h"
#include "render/sampling.h"
#include "render/scene.h"
#include "render/scene_loader.h"

namespace irfarm {
namespace {

// Records on the walls of a [-1,1]^3 room with validity radii a*R of 0.5 to 2 times the mean
// record spacing (a = 0.1): the density of a real cache, where a lookup sees a few records.
// `linear_fit`: CacheSettings::linear_fit (the renderer's default), or Ward's weighted mean.
std::unique_ptr<IrradianceCache> MakeCache(int n, bool linear_fit) {
  CacheSettings cs;
  cs.linear_fit = linear_fit;
  cs.bounds.Extend(Vec3(-1, -1, -1));
  cs.bounds.Extend(Vec3(1, 1, 1));
  cs.max_accuracy = 0.2f;
  auto cache = std::make_unique<IrradianceCache>(cs);
  Rng rng(1, 2);
  for (int i = 0; i < n; ++i) {
    const int axis = int(rng.Next() * 3) % 3;
    const float side = rng.Next() < 0.5f ? -1.0f : 1.0f;
    IrradianceRecord r;
    r.position = Vec3(rng.Next() * 2 - 1, rng.Next() * 2 - 1, rng.Next() * 2 - 1);
    r.position[axis] = side;
    r.normal = Vec3(0, 0, 0);
    r.normal[axis] = -side;
    r.irradiance = Vec3(rng.Next(), rng.Next(), rng.Next());
    r.radius = (0.5f + 1.5f * rng.Next()) * std::sqrt(24.0f / float(n)) / 0.1f;
    cache->Insert(r);
  }
  return cache;
}

void BM_CacheLookup(benchmark::State& state) {
  const auto cache = MakeCache(int(state.range(0)), state.range(1) != 0);
  Rng rng(3, 4);
  int hits = 0;
  for (auto _ : state) {
    Vec3 x(rng.Next() * 2 - 1, rng.Next() * 2 - 1, -1), E;
    LookupInfo info;
    hits += cache->Lookup(x, Vec3(0, 0, 1), 0.1f, &E, &info);
    benchmark::DoNotOptimize(E);
  }
  state.counters["hit_rate"] = double(hits) / double(state.iterations());
  const CacheMemory m = cache->MemoryUse();
  state.counters["bytes_per_record"] = double(m.bytes_per_record);
  state.counters["octree_per_record_bytes"] = double(m.octree_bytes) / double(m.record_bytes);
}
// Second argument: 1 = linear fit (the renderer's lookups), 0 = Ward's weighted mean.
BENCHMARK(BM_CacheLookup)->ArgsProduct({{1000, 10000, 100000}, {1, 0}});

// A worker's publisher takes the records its threads made since its last pass (every 50 ms),
// from a cache that also holds everything else: the whole cache walked for them (arg 1 = 0, as
// the worker did before ForEachNewer) or the walk stopped at the previous pass's mark (arg 1 = 1).
// 64 new records on top of `n`; both copy the same 64.
void BM_NewRecordsWalk(benchmark::State& state) {
  const int n = int(state.range(0));
  const auto cache = MakeCache(n, true);
  const uint64_t mark = cache->ForEachNewer(0, [](const IrradianceRecord&) {});
  Rng rng(5, 6);
  for (int i = 0; i < 64; ++i) {
    IrradianceRecord r;
    r.position = Vec3(rng.Next() * 2 - 1, rng.Next() * 2 - 1, -1);
    r.normal = Vec3(0, 0, 1);
    r.irradiance = Vec3(1);
    r.radius = std::sqrt(24.0f / float(n)) / 0.1f;
    r.level = 1;  // not among the n (level 0): what the walk keeps
    cache->Insert(r);
  }
  std::vector<IrradianceRecord> fresh;
  for (auto _ : state) {
    fresh.clear();
    const auto keep = [&](const IrradianceRecord& r) {
      if (r.level == 1) fresh.push_back(r);
    };
    if (state.range(1) != 0)
      cache->ForEachNewer(mark, keep);
    else
      cache->ForEach(keep);
    benchmark::DoNotOptimize(fresh.data());
  }
  state.counters["taken"] = double(fresh.size());
}
BENCHMARK(BM_NewRecordsWalk)
    ->ArgsProduct({{10000, 40000, 400000}, {0, 1}})
    ->Unit(benchmark::kMicrosecond);

// The same cache and lookups in runs of 16, one run per pixel, as a pixel's camera samples land:
// uniformly over a pixel footprint of half the mean record spacing (caches of real renders hold
// 0.1-0.5 records per pixel, so this is the dense end), through LookupNear with one region as
// the final pass uses it (2 footprints, 0.1 rad). Time per lookup, gathers included.
void BM_CacheLookupPixelRuns(benchmark::State& state) {
  const int n = int(state.range(0));
  const auto cache = MakeCache(n, state.range(1) != 0);
  const float footprint = 0.5f * std::sqrt(24.0f / float(n));
  Rng rng(3, 4);
  LookupRegion region;
  int hits = 0, reused = 0, k = 0;
  double region_records = 0;
  Vec3 pixel;
  for (auto _ : state) {
    if (k++ % 16 == 0) pixel = Vec3(rng.Next() * 2 - 1, rng.Next() * 2 - 1, -1);
    const Vec3 x = pixel + Vec3(rng.Next() * footprint, rng.Next() * footprint, 0);
    Vec3 E;
    LookupInfo info;
    hits += cache->LookupNear(x, Vec3(0, 0, 1), 0.1f, 2 * footprint, 0.1f, &region, &E, &info);
    reused += info.from_region;
    region_records += std::max(0, region.count);
    benchmark::DoNotOptimize(E);
  }
  state.counters["hit_rate"] = double(hits) / double(state.iterations());
  state.counters["from_region"] = double(reused) / double(state.iterations());
  state.counters["region_records"] = region_records / double(state.iterations());
}
BENCHMARK(BM_CacheLookupPixelRuns)->ArgsProduct({{1000, 10000, 100000}, {1, 0}});

std::unique_ptr<Scene> CornellBox() {
  absl::StatusOr<PreparedRender> prepared = PrepareRender(
      std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml", {}, RenderRequest{});
  return prepared.ok() ? std::move(prepared->scene) : nullptr;
}

void BM_Intersect(benchmark::State& state) {
  const auto scene = CornellBox();
  if (!scene) return state.SkipWithError("cannot load cornell-box");
  Rng rng(5, 6);
  for (auto _ : state) {
    const Ray ray{Vec3(0, 0, 0), UniformSphere(rng.Next(), rng.Next()), INFINITY};
    SurfaceHit hit;
    benchmark::DoNotOptimize(scene->Intersect(ray, &hit));
  }
}
BENCHMARK(BM_Intersect);

void BM_Occluded(benchmark::State& state) {
  const auto scene = CornellBox();
  if (!scene) return state.SkipWithError("cannot load cornell-box");
  Rng rng(7, 8);
  for (auto _ : state) {
    Ray ray{Vec3(0, 0, 0), UniformSphere(rng.Next(), rng.Next()), 0.5f};
    benchmark::DoNotOptimize(scene->Occluded(ray));
  }
}
BENCHMARK(BM_Occluded);

// A record's Hessian spacing (EstimateIrradianceDerivatives) on the default 22 x 70 strata of a
// cluttered hemisphere (hit distances and values varying from stratum to stratum), per record.
void BM_RecordDerivatives(benchmark::State& state) {
  const int T = 22, P = 70;
  Rng rng(3, 5);
  std::vector<Vec3> pts(size_t(T * P));
  std::vector<float> lum(size_t(T * P));
  double sum = 0;
  for (int i = 0; i < T; ++i)
    for (int j = 0; j < P; ++j) {
      const Vec3 d = StratifiedCosineHemisphere(i, j, T, P, rng.Next(), rng.Next());
      pts[size_t(i * P + j)] = d * (0.5f + 2 * rng.Next());
      lum[size_t(i * P + j)] = 0.2f + rng.Next();
      sum += lum[size_t(i * P + j)];
    }
  IrradianceDerivatives d;
  for (auto _ : state) {
    benchmark::DoNotOptimize(EstimateIrradianceDerivatives(T, P, pts.data(), lum.data(),
                                                           float(sum / (T * P)), Vec3(0, 0, 1),
                                                           Vec3(1, 0, 0), Vec3(0, 1, 0), &d));
  }
}
BENCHMARK(BM_RecordDerivatives)->Unit(benchmark::kMicrosecond);

// A visible normal of the Beckmann distribution (Mitsuba's default for rough conductors and
// plastics), alpha 0.2, for directions uniform in cos(theta), per sample.
void BM_BeckmannSample(benchmark::State& state) {
  const Microfacet mf(MicrofacetType::kBeckmann, 0.2f, 0.2f);
  Rng rng(7, 9);
  for (auto _ : state) {
    const float c = std::max(1e-3f, rng.Next()), s = std::sqrt(1 - c * c);
    benchmark::DoNotOptimize(mf.Sample(Vec3(s, 0, c), rng.Next(), rng.Next()));
  }
}
BENCHMARK(BM_BeckmannSample);

// core/fast_trig.h's Atan2 against libm's, side by side in one run (arg 0: libm, 1: ours), on what
// PolygonProjectedSolidAngle passes: (sin, cos) pairs of angles in [0, pi].
void BM_Atan2(benchmark::State& state) {
  const bool fast = state.range(0) == 1;
  std::vector<double> y(1024), x(1024);
  for (size_t i = 0; i < y.size(); ++i) {
    const double a = 3.14159265358979 * (double(i) * 0.618034 - std::floor(double(i) * 0.618034));
    y[i] = std::sin(a);
    x[i] = std::cos(a);
  }
  for (auto _ : state) {
    double acc = 0;
    for (size_t i = 0; i < y.size(); ++i) acc += fast ? Atan2(y[i], x[i]) : std::atan2(y[i], x[i]);
    benchmark::DoNotOptimize(acc);
  }
  state.SetItemsProcessed(state.iterations() * int64_t(y.size()));
}
BENCHMARK(BM_Atan2)->Arg(0)->Arg(1);

// A tube lamp as a cylinder shape is tessellated (256 segments, 1.5 m long, 5 cm radius, emitting
// outwards) under a 6 x 3 x 6 m room's ceiling: one light-tree pick (Sample) per iteration, at
// shading points spread through the room with random normals facing up or sideways (those the
// lamp can light); with argument 1 also the Pmf of the pick (what MIS asks of a triangle a BSDF
// ray found).
std::vector<LightTriangle> TubeLamp() {
  std::vector<LightTriangle> tris;
  constexpr int kSegments = 256;
  const Vec3 base(2, 2.6f, 3);
  for (int s = 0; s < kSegments; ++s) {
    const float a0 = 2 * kPi * float(s) / kSegments, a1 = 2 * kPi * float(s + 1) / kSegments;
    const auto at = [&](float a, float x) {
      return base + Vec3(x, 0.05f * std::cos(a), 0.05f * std::sin(a));
    };
    const Vec3 q[4] = {at(a0, 0), at(a1, 0), at(a1, 1.5f), at(a0, 1.5f)};
    for (const auto& [i, j, k] : {std::array<int, 3>{0, 2, 1}, std::array<int, 3>{0, 3, 2}}) {
      LightTriangle t;
      t.p0 = q[i];
      t.p1 = q[j];
      t.p2 = q[k];
      const Vec3 c = Cross(t.p1 - t.p0, t.p2 - t.p0);
      t.area = 0.5f * Length(c);
      t.ng = Normalize(c);
      t.n0 = t.n1 = t.n2 = t.ng;
      tris.push_back(t);
    }
  }
  return tris;
}
void BM_LightTreeSample(benchmark::State& state) {
  LightTree tree;
  tree.Build(TubeLamp(), 1.0f);
  Rng rng(5, 6);
  std::vector<std::pair<Vec3, Vec3>> points;
  while (points.size() < 1024) {  // where the lamp can light (the light sampler tests the root)
    const Vec3 p(6 * rng.Next(), 2.5f * rng.Next(), 6 * rng.Next());
    const Vec3 n = Normalize(Vec3(rng.Next() - 0.5f, rng.Next(), rng.Next() - 0.5f));
    if (tree.Importance(p, n) > 0) points.emplace_back(p, n);
  }
  size_t i = 0;
  int found = 0;
  for (auto _ : state) {
    const auto& [p, n] = points[i++ & 1023];
    float pmf;
    const int t = tree.Sample(p, n, rng.Next(), &pmf);
    found += t >= 0;
    if (state.range(0) != 0 && t >= 0) benchmark::DoNotOptimize(tree.Pmf(p, n, unsigned(t)));
  }
  state.counters["found"] = double(found) / double(state.iterations());
}
BENCHMARK(BM_LightTreeSample)->Arg(0)->Arg(1);

}  // namespace
}  // namespace irfarm

BENCHMARK_MAIN();

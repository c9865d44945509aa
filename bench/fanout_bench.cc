// Micro-benchmark (Google Benchmark) of the filtered fan-out's receiver selection per record:
// FanoutIndex::Query (the grid over the workers' regions, coordinator/fanout_index.h) against
// QueryAll (every worker's region tested, as the coordinator did before the grid), on the same
// regions and records, for 16 to 1024 workers. Regions are tile-sized boxes (1/20 of the scene's
// side) scattered over a 10 x 3 x 10 scene, records anywhere in it with reaches a R of 0.1% to 3%
// of the scene's diagonal (a few pixel footprints at production resolution). Ratios between the
// two, at the same worker count in one run, are the figure; absolute times depend on the load.
// Run: build/bench/bench_fanout.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "coordinator/fanout_index.h"

namespace irfarm {
namespace {

struct Setup {
  FanoutIndex index;
  std::vector<IrradianceRecord> records;
};

Setup Make(int workers) {
  Setup s;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0, 1);
  Bounds3 scene;
  scene.Extend(Vec3(0, 0, 0));
  scene.Extend(Vec3(10, 3, 10));
  std::vector<FanoutIndex::Entry> entries;
  for (int i = 0; i < workers; ++i) {
    const Vec3 c(10 * u(rng), 3 * u(rng), 10 * u(rng));
    Bounds3 b;
    b.Extend(Max(scene.lo, c - Vec3(0.25f, 0.08f, 0.25f)));
    b.Extend(Min(scene.hi, c + Vec3(0.25f, 0.08f, 0.25f)));
    entries.push_back({uint32_t(i + 1), b});
  }
  s.index.Build(scene, entries);
  const float diag = Length(scene.Diagonal());
  for (int i = 0; i < 4096; ++i) {
    IrradianceRecord r;
    r.position = Vec3(10 * u(rng), 3 * u(rng), 10 * u(rng));
    r.normal = Vec3(0, 1, 0);
    r.irradiance = Vec3(1);
    r.radius = diag * (0.001f + 0.029f * u(rng)) / 0.2f;  // reach a R with a = 0.2
    s.records.push_back(r);
  }
  return s;
}

void Run(benchmark::State& state, bool grid) {
  Setup s = Make(int(state.range(0)));
  std::vector<uint32_t> out;
  size_t i = 0, reached = 0;
  for (auto _ : state) {
    const IrradianceRecord& r = s.records[i++ % s.records.size()];
    if (grid)
      s.index.Query(r, 0.2f, &out);
    else
      s.index.QueryAll(r, 0.2f, &out);
    reached += out.size();
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["receivers"] = double(reached) / double(state.iterations());
}

void BM_FanoutGrid(benchmark::State& state) { Run(state, true); }
void BM_FanoutBruteForce(benchmark::State& state) { Run(state, false); }
BENCHMARK(BM_FanoutGrid)->Arg(16)->Arg(64)->Arg(256)->Arg(1024);
BENCHMARK(BM_FanoutBruteForce)->Arg(16)->Arg(64)->Arg(256)->Arg(1024);

}  // namespace
}  // namespace irfarm

BENCHMARK_MAIN();

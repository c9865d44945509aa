// Record cost (issue 9): rays per second inside IrrcacheIntegrator::ComputeRecord against a bare
// Embree loop (rtcIntersect1 and nothing else) over record hemispheres from the same points, on
// cornell-box (a few dozen triangles) and veach-ajar (many triangles), in the same run.
//
// The points are the first diffuse hits of camera rays through a grid of pixel centres. A record
// traces T x P hemisphere rays and continues each as a path (bounce and shadow rays); every Embree
// call it makes is counted (RenderCounters: record, bounce and shadow rays). The bare loop traces
// one T x P stratified cosine hemisphere per point, built the same way (same frame, same strata),
// with closest-hit rtcIntersect1 only. A second bare loop replays the records' own rays: every
// ray the records traced once before the timed loops (Scene's ray log: hemisphere, bounce and
// shadow rays, in their order), as rtcIntersect1 and rtcOccluded1 calls and nothing else; bounce
// and shadow rays start at scattered points and cost Embree more than a hemisphere from one
// point. Reported: the rates, the ratio against the hemisphere loop (`ratio`) and against the
// replay of the same rays (`ratio_same_rays`; goal >= 0.8), and the hemisphere rays traced as
// rtcIntersect8 and rtcIntersect16 packets (bare8, bare16), to see whether packets for a
// record's first hits would pay. Also what the goal leaves a record for all but Embree
// (`non_embree_budget_us_at_0.8`: the replay's time for its rays x (1 / 0.8 - 1)) beside what the
// Hessian spacing alone costs it (`hessian_us_per_record`: the same records timed with Ward's
// split-sphere spacing, alternately, subtracted).
// Run: build/bench/bench_record (one thread; the loops alternate within each iteration, timed
// in thread CPU time).
#include <benchmark/benchmark.h>

#include <time.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "render/bsdfs/bsdf.h"
#include "render/irrcache_integrator.h"
#include "render/pipeline.h"
#include "render/renderer.h"
#include "render/sampling.h"
#include "render/scene.h"
#include "render/scene_loader.h"

namespace irfarm {
namespace {

// This thread's CPU time in seconds: the machine is shared, and wall time would count the time
// other processes hold the core.
double ThreadSeconds() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

struct RecordPoint {
  SurfaceHit hit;
  Vec3 nf;
  float pixel_spread;
};

struct Fixture {
  std::unique_ptr<Scene> scene;
  RenderSettings settings;
  std::vector<RecordPoint> points;
  std::vector<RTCRayHit> bare_rays;  // T x P per point, prepared outside the timed loop
  std::vector<TracedRay> replay;     // the records' own rays, logged once
};

// Loads a test scene and finds up to `grid` x `grid` record points (diffuse first hits).
std::unique_ptr<Fixture> MakeFixture(const std::string& name, int grid) {
  const std::string path = std::string(IRFARM_TEST_DATA) + "/scenes/" + name + "/scene.xml";
  RenderRequest request;
  request.integrator = "irrcache";
  absl::StatusOr<PreparedRender> prepared = PrepareRender(path, {}, request);
  if (!prepared.ok()) return nullptr;
  auto f = std::make_unique<Fixture>();
  f->scene = std::move(prepared->scene);
  f->settings = prepared->settings;
  const Camera& cam = f->scene->camera();
  for (int gy = 0; gy < grid; ++gy) {
    for (int gx = 0; gx < grid; ++gx) {
      const Vec3 dir =
          cam.Direction((gx + 0.5f) * cam.width() / grid, (gy + 0.5f) * cam.height() / grid);
      RecordPoint p;
      if (!f->scene->Intersect(Ray{cam.origin(), dir, INFINITY}, &p.hit)) continue;
      // Points with a diffuse lobe seen from its front (where records are made).
      const Bsdf& m = f->scene->material(p.hit.material);
      const ShadingFrame frame = p.hit.Frame();
      const Vec3 wo_l = frame.ToLocal(-dir);
      if (IsBlack(m.DiffuseAlbedo(p.hit.Context(), wo_l))) continue;
      p.nf = wo_l.z >= 0 ? p.hit.ns : -p.hit.ns;
      p.pixel_spread = cam.PixelSpread(p.hit.t);
      f->points.push_back(p);
    }
  }
  // The bare loop's rays: the record's strata and frame, origins offset the same way.
  IrrcacheIntegrator integrator(*f->scene, nullptr, f->settings.irrcache);
  const int T = integrator.strata_theta(), P = integrator.strata_phi();
  Rng rng(11, 12);
  for (const RecordPoint& p : f->points) {
    Vec3 s, t;
    MakeFrame(p.nf, &s, &t);
    const Vec3 ng_side = Dot(p.hit.ng, p.nf) >= 0 ? p.hit.ng : -p.hit.ng;
    for (int i = 0; i < T; ++i) {
      for (int j = 0; j < P; ++j) {
        const float u = rng.Next(), v = rng.Next();
        const Vec3 local = StratifiedCosineHemisphere(i, j, T, P, u, v);
        const Vec3 dir = s * local.x + t * local.y + p.nf * local.z;
        if (Dot(dir, ng_side) <= 0) continue;
        const Ray ray = Scene::SpawnRay(p.hit.p, p.hit.ng, p.hit.error_scale, dir);
        f->bare_rays.push_back(Scene::ToRtcRayHit(ray));
      }
    }
  }
  // The records' own rays: one pass of the records with the scene's ray log on.
  RenderCounters counters;
  Rng record_rng(3, 4);
  f->scene->set_ray_log(&f->replay);
  for (const RecordPoint& p : f->points)
    integrator.ComputeRecord(p.hit, p.nf, 1, p.pixel_spread, record_rng, counters);
  f->scene->set_ray_log(nullptr);
  return f;
}

// Traces `rays` as packets of N (RTCRayHit8 or RTCRayHit16) with closest-hit queries and nothing
// else; the last packet's unused lanes are masked off. Returns the hits.
template <typename Packet, int N>
uint64_t TracePackets(RTCScene scene, const std::vector<RTCRayHit>& rays) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  uint64_t hits = 0;
  for (size_t i0 = 0; i0 < rays.size(); i0 += N) {
    Packet packet;
    alignas(64) int valid[N];
    for (int k = 0; k < N; ++k) {
      const bool on = i0 + k < rays.size();
      valid[k] = on ? -1 : 0;
      const RTCRayHit& rh = rays[on ? i0 + k : i0];
      packet.ray.org_x[k] = rh.ray.org_x;
      packet.ray.org_y[k] = rh.ray.org_y;
      packet.ray.org_z[k] = rh.ray.org_z;
      packet.ray.dir_x[k] = rh.ray.dir_x;
      packet.ray.dir_y[k] = rh.ray.dir_y;
      packet.ray.dir_z[k] = rh.ray.dir_z;
      packet.ray.tnear[k] = rh.ray.tnear;
      packet.ray.tfar[k] = rh.ray.tfar;
      packet.ray.mask[k] = rh.ray.mask;
      packet.ray.flags[k] = 0;
      packet.ray.time[k] = 0;
      packet.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
      packet.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
    }
    if constexpr (N == 8) {
      rtcIntersect8(valid, scene, &ctx, &packet);
    } else {
      rtcIntersect16(valid, scene, &ctx, &packet);
    }
    for (int k = 0; k < N; ++k) hits += valid[k] && packet.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;
  }
  return hits;
}

// Makes one record at each of the fixture's points with `integrator`; returns the thread time.
double MakeRecords(const Fixture& f, const IrrcacheIntegrator& integrator, Rng& rng,
                   RenderCounters& counters) {
  const double t0 = ThreadSeconds();
  for (const RecordPoint& p : f.points)
    benchmark::DoNotOptimize(
        integrator.ComputeRecord(p.hit, p.nf, 1, p.pixel_spread, rng, counters));
  return ThreadSeconds() - t0;
}

void BM_RecordVsBareEmbree(benchmark::State& state, const char* name) {
  const std::unique_ptr<Fixture> f = MakeFixture(name, 12);
  if (!f || f->points.empty()) return state.SkipWithError("cannot load the scene");
  IrrcacheIntegrator integrator(*f->scene, nullptr, f->settings.irrcache);
  RenderCounters counters;
  Rng rng(1, 2);
  double record_seconds = 0, bare_seconds = 0;
  uint64_t bare_rays = 0, bare_hits = 0, packet_hits = 0, packet16_hits = 0;
  double packet_seconds = 0, packet16_seconds = 0, replay_seconds = 0;
  uint64_t replay_rays = 0, replay_hits = 0;
  std::vector<RTCRayHit> rays = f->bare_rays;
  // The same records with Ward's split-sphere spacing: the difference in time is what the
  // Hessian spacing (EstimateIrradianceDerivatives) costs a record.
  IrrcacheSettings split = f->settings.irrcache;
  split.spacing = RecordSpacing::kSplitSphere;
  const IrrcacheIntegrator split_integrator(*f->scene, nullptr, split);
  RenderCounters split_counters;
  Rng split_rng(1, 2);
  double split_seconds = 0;
  for (auto _ : state) {
    split_seconds += MakeRecords(*f, split_integrator, split_rng, split_counters);
    const double t0 = ThreadSeconds();
    MakeRecords(*f, integrator, rng, counters);
    const double t1 = ThreadSeconds();
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (size_t i = 0; i < rays.size(); ++i) {
      RTCRayHit rh = f->bare_rays[i];
      rtcIntersect1(f->scene->embree_scene(), &ctx, &rh);
      bare_hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }
    const double t2 = ThreadSeconds();
    // The same rays as packets of 8 and of 16 (a record's hemisphere rays share their origin):
    // would rtcIntersect8 or rtcIntersect16 pay for the first hits?
    packet_hits += TracePackets<RTCRayHit8, 8>(f->scene->embree_scene(), f->bare_rays);
    const double t2b = ThreadSeconds();
    packet16_hits += TracePackets<RTCRayHit16, 16>(f->scene->embree_scene(), f->bare_rays);
    const double t3 = ThreadSeconds();
    // The records' own rays, bare.
    for (const TracedRay& tr : f->replay) {
      if (tr.shadow) {
        RTCRay r = Scene::ToRtcRay(tr.ray);
        rtcOccluded1(f->scene->embree_scene(), &ctx, &r);
        replay_hits += r.tfar < 0;
      } else {
        RTCRayHit rh = Scene::ToRtcRayHit(tr.ray);
        rtcIntersect1(f->scene->embree_scene(), &ctx, &rh);
        replay_hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      }
    }
    const double t4 = ThreadSeconds();
    replay_seconds += t4 - t3;
    replay_rays += f->replay.size();
    packet_seconds += t2b - t2;
    packet16_seconds += t3 - t2b;
    bare_rays += rays.size();
    record_seconds += t1 - t0;
    bare_seconds += t2 - t1;
    state.SetIterationTime(t4 - t0);
  }
  const double record_rays =
      double(counters.record_rays + counters.bounce_rays + counters.shadow_rays);
  const double record_rate = record_rays / record_seconds;
  const double bare_rate = double(bare_rays) / bare_seconds;
  state.counters["points"] = double(f->points.size());
  state.counters["record_Mrays_s"] = record_rate * 1e-6;
  state.counters["bare_Mrays_s"] = bare_rate * 1e-6;
  state.counters["ratio"] = record_rate / bare_rate;
  const double replay_rate = double(replay_rays) / replay_seconds;
  state.counters["replay_Mrays_s"] = replay_rate * 1e-6;
  state.counters["ratio_same_rays"] = record_rate / replay_rate;
  // The log holds as many rays per record as the counters count (a check on the replay).
  state.counters["replay_rays_per_record"] = double(f->replay.size()) / double(f->points.size());
  benchmark::DoNotOptimize(replay_hits);
  state.counters["bare8_Mrays_s"] = double(bare_rays) / packet_seconds * 1e-6;
  state.counters["bare16_Mrays_s"] = double(bare_rays) / packet16_seconds * 1e-6;
  state.counters["hits_8_vs_1"] = double(packet_hits) / double(bare_hits);
  state.counters["hits_16_vs_1"] = double(packet16_hits) / double(bare_hits);
  state.counters["rays_per_record"] = record_rays / double(counters.records_computed);
  state.counters["bare_hit_frac"] = double(bare_hits) / double(bare_rays);
  state.counters["us_per_record"] = record_seconds / double(counters.records_computed) * 1e6;
  // What the goal (ratio_same_rays >= 0.8) leaves a record for everything but Embree: the replay's
  // time for the record's rays, times 1 / 0.8 - 1; against it, the Hessian spacing's own cost.
  const double replay_us_per_record =
      record_rays / double(counters.records_computed) / replay_rate * 1e6;
  state.counters["replay_us_per_record"] = replay_us_per_record;
  state.counters["non_embree_budget_us_at_0.8"] = replay_us_per_record * (1 / 0.8 - 1);
  state.counters["hessian_share"] =
      double(counters.records_hessian) / double(counters.records_computed);
  state.counters["hessian_us_per_record"] =
      (record_seconds / double(counters.records_computed) -
       split_seconds / double(split_counters.records_computed)) *
      1e6;
}
// The records alone, many times over (no bare loops): for a profiler, e.g.
// perf record -g build/bench/bench_record --benchmark_filter=RecordsOnly/cornell
void BM_RecordsOnly(benchmark::State& state, const char* name) {
  const std::unique_ptr<Fixture> f = MakeFixture(name, 12);
  if (!f || f->points.empty()) return state.SkipWithError("cannot load the scene");
  IrrcacheIntegrator integrator(*f->scene, nullptr, f->settings.irrcache);
  RenderCounters counters;
  Rng rng(1, 2);
  for (auto _ : state) MakeRecords(*f, integrator, rng, counters);
  state.counters["us_per_record"] = benchmark::Counter(
      double(counters.records_computed), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["record_rays"] = double(counters.record_rays) / double(counters.records_computed);
  state.counters["bounce_rays"] = double(counters.bounce_rays) / double(counters.records_computed);
  state.counters["shadow_rays"] = double(counters.shadow_rays) / double(counters.records_computed);
}
BENCHMARK_CAPTURE(BM_RecordsOnly, cornell_box, "cornell-box")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RecordsOnly, veach_ajar, "veach-ajar")->Unit(benchmark::kMillisecond);

BENCHMARK_CAPTURE(BM_RecordVsBareEmbree, cornell_box, "cornell-box")
    ->UseManualTime()
    ->Iterations(5)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RecordVsBareEmbree, veach_ajar, "veach-ajar")
    ->UseManualTime()
    ->Iterations(5)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace irfarm

BENCHMARK_MAIN();

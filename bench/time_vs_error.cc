// Time against error, side by side in one run: for each scene, irfarm's `irrcache` at its
// default settings and irfarm's own `path` at a ladder of spp, each timed (wall seconds of the
// render phases) and compared with the Mitsuba reference (relMSE). Path tracing's relMSE falls as
// 1/spp, so path's time for irrcache's relMSE is t(spp_k) * relMSE(spp_k) / relMSE_irrcache from
// its largest run; the ratio of that to irrcache's time is the speed-up at equal error. Mitsuba's
// own relMSE at 256 spp (mitsuba-curve.json) is printed next to it.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "render/image.h"
#include "render/renderer.h"
#include "render/scene.h"
#include "render/scene_loader.h"

namespace irfarm {
namespace {

// Mitsuba's relMSE at `spp` from mitsuba-curve.json (points[].spp, points[].relmse_mean); -1 if
// the file or the point is missing. A tiny scan, enough for the file our tools write.
double MitsubaRelmse(const std::string& path, int spp) {
  std::ifstream f(path);
  if (!f) return -1;
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string s = ss.str();
  const std::string key = "\"spp\": " + std::to_string(spp) + ",";
  const size_t at = s.find(key);
  if (at == std::string::npos) return -1;
  const size_t r = s.find("\"relmse_mean\":", at);
  if (r == std::string::npos) return -1;
  return std::atof(s.c_str() + r + 14);
}

struct Run {
  std::string method;
  int spp;
  double seconds, relmse;
  uint64_t records;
};

}  // namespace
}  // namespace irfarm

int main(int argc, char** argv) {
  using namespace irfarm;
  CLI::App app{"irrcache vs path: wall time against relMSE"};
  std::string dir = IRFARM_SHARED_SCENES;
  std::vector<std::string> scenes = {"cornell-box", "sunlit-room"};
  std::vector<int> path_spp = {16, 64, 256};
  int threads = 0;
  app.add_option("--scenes-dir", dir, "folder of <scene>/scene.xml + reference.exr");
  app.add_option("--scenes", scenes, "scene names")->delimiter(',');
  app.add_option("--path-spp", path_spp, "spp ladder for path")->delimiter(',');
  app.add_option("--threads", threads, "threads (default all)");
  CLI11_PARSE(app, argc, argv);

  int failures = 0;
  for (const std::string& name : scenes) {
    const std::string base = dir + "/" + name;
    absl::StatusOr<SceneDesc> desc = LoadSceneFile(base + "/scene.xml", LoadOptions{});
    absl::StatusOr<Image> ref = ReadExr(base + "/reference.exr");
    if (!desc.ok() || !ref.ok()) {
      std::fprintf(stderr, "%s: %s\n", name.c_str(),
                   std::string((desc.ok() ? ref.status() : desc.status()).message()).c_str());
      ++failures;
      continue;
    }
    absl::StatusOr<std::unique_ptr<Scene>> scene = Scene::Build(*desc);
    if (!scene.ok()) {
      std::fprintf(stderr, "%s\n", std::string(scene.status().message()).c_str());
      ++failures;
      continue;
    }
    std::vector<Run> runs;
    auto run = [&](const std::string& integrator, int spp) {
      RenderSettings s = *SettingsForScene(*desc, integrator);
      if (spp > 0) s.spp = spp;
      s.threads = threads;
      s.seed = 7;
      RenderOutput out = Render(**scene, s);
      const double secs = out.stats.PhaseWall("pilot") + out.stats.PhaseWall("overture") +
                          out.stats.PhaseWall("render");
      runs.push_back(Run{integrator, s.spp, secs, CompareImages(out.image, *ref).relmse,
                         out.stats.counters.records_computed});
      std::printf("  %-9s spp %5d  %8.2f s  relMSE %.3e  records %llu\n", integrator.c_str(), s.spp,
                  secs, runs.back().relmse, static_cast<unsigned long long>(runs.back().records));
      std::fflush(stdout);
    };
    std::printf("%s (%dx%d)\n", name.c_str(), desc->camera.width, desc->camera.height);
    run("irrcache", 0);
    for (int spp : path_spp) run("path", spp);
    const Run& irr = runs[0];
    const Run& best = runs.back();
    const double path_equal = best.seconds * best.relmse / irr.relmse;
    const double mitsuba = MitsubaRelmse(base + "/mitsuba-curve.json", 256);
    std::printf("  => path needs ~%.2f s for irrcache's relMSE %.3e: irrcache is %.2fx faster\n",
                path_equal, irr.relmse, path_equal / irr.seconds);
    if (mitsuba > 0)
      std::printf("  => Mitsuba 256 spp relMSE %.3e: irrcache/Mitsuba256 = %.2f (%s)\n", mitsuba,
                  irr.relmse / mitsuba, irr.relmse < mitsuba ? "below" : "NOT below");
  }
  return failures ? 1 : 0;
}

// Property test over random scenes (issue 10, part 8): 200 scenes from fixed seeds, each a few
// boxes, spheres, slivers (rectangles 1e-4 thin), coincident faces (two rectangles on the same
// plane), tiny (1e-5) and huge (1e4) rectangles, lit by random point lights, area lights and
// sometimes a constant environment, the whole scene scaled by 1e-2..1e2 and, for a quarter of
// them, moved far from the origin (up to 1e6). Every scene is loaded through the XML loader (so
// the re-centring of far scenes is exercised) and rendered with both integrators at 16x16.
// Properties: no NaN, no infinity, no negative pixel, no non-finite sample counted; the mean of
// the irrcache image is within the noise of the two integrators (4 standard errors, each
// estimated from two independent seeds of the same integrator) plus Ward's accuracy `a` times
// the mean (the relative interpolation error the cache is built to allow; the record rays are
// path traced, so the cache is otherwise unbiased) of the path tracer's mean.
// Four scenes are rendered at 48 x 48 (kCoarseScenes: at 16 x 16 the cache's pixel-based record
// spacing is too coarse for them), where path finds no light at 16 spp it is rendered again at
// more (kRareLightSpp), and one scene whose irrcache mean is heavy-tailed is left out of the mean
// property (kHeavyTailedScenes).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "render_test_util.h"

namespace irfarm {
namespace {

constexpr int kScenes = 200;
constexpr int kRes = 16;
constexpr int kSpp = 16;

// Scenes rendered at kCoarseRes instead of kRes. At 16 x 16 a few records cover the whole image
// (records are at least min_spacing_px = 1.5 pixels apart and a visible face is 3-4 pixels wide),
// so where indirect light varies steeply across a face the image is off by more than the accuracy
// allows; at 48 x 48 and above irrcache and path agree. Measured (means, path at 256-1024 spp):
//   115 (boxes beside a point light): irrcache 6.8e-4 at 16 x 16, 1.18e-3 at 48 x 48, 1.23e-3 at
//       128 x 128; path 1.25e-3. At 16 x 16 it failed 4 runs in 5, right at the bound.
//   65 (coincident faces, a disk, a tiny and a huge rectangle, an area light): irrcache 1.16e-2 at
//       16 x 16 (17% low), 1.37e-2 at 48 x 48, 1.40e-2 at 64 x 64; path 1.40e-2.
//   54, 132 (slivers, boxes, a tiny rectangle; light reaches the visible surfaces only along rare
//       paths): irrcache 2.4e-6 and 1.9e-7 at 16 x 16, 5.8e-6 and 1.1e-7 at 64 x 64; path (256
//       spp) 8.0e-6 and 1.5e-7 at 64 x 64.
// These three were listed until 2026-12-01 as bugs ("a leak of cached irradiance", "coincident
// faces 21% low"); the measurements above show they were the resolution and path's own
// sampling (see kRareLightSpp).
constexpr int kCoarseScenes[] = {54, 65, 115, 132};
// Scenes left out of the mean property (still checked for NaN, infinity, negatives): light
// reaches the image only along rare paths, which a record's 1536 rays catch a few times or not at
// all, and each catch is interpolated over many pixels, so irrcache's mean is heavy-tailed from
// run to run (threads change which records are made). Scene 54 at 48 x 48, 16 spp, six runs:
// 0, 8.5e-7, 1.1e-6, 4.1e-6, 8.0e-6, 8.1e-6 (and 3.0e-5 once in the test); path 5.8e-6 +- 1.7e-6.
// A weakness of irradiance caching with rare indirect light, not of this scene's set-up.
// Scene 132 likewise (2026-12-05, after the pilot's level choice changed which pilot runs, and so
// its timings under load): 48 x 48, 16 spp, seeds 3-6, one level 6.6e-8 to 2.4e-7, two levels
// 5.4e-8 to 1.4e-7; path 1.48e-7 at 65,536 spp, while the test's two 16-spp path images gave
// 9.3e-8 +- 1.8e-8 (their standard error misses the tail) and failed irrcache's 1.97e-7 under a
// loaded ctest run.
// Scene 157 likewise (2026-12-07, when the cube's (u, v) became Mitsuba's: its tangents turn
// the record rays' frames, so other rays catch the light): a far, tiny scene whose light reaches
// 12 of 256 pixels along rare paths; path gives 0 at 16 and 256 spp, 2.89e-8 at 65,536 spp
// (seed 9), irrcache 2.95e-8 +- 0.37e-8 at 16 spp (seeds 3 and 4).
constexpr int kHeavyTailedScenes[] = {54, 132, 157};
constexpr int kCoarseRes = 48;
// When both path renders are black and irrcache's are not, the light reaches the image only along
// paths too rare for kSpp samples (path's standard error is then estimated as 0): path is
// rendered again at kRareLightSpp to have a mean and an error to compare with.
constexpr int kRareLightSpp = 16 * kSpp;

// One random scene, as Mitsuba XML. Local coordinates: objects in [-1, 1]^3, camera 4 units from
// the origin; every position is then scaled by `scale_` and moved by `offset_` (in double, and
// printed with 17 digits, so the loader sees the far scene exactly).
class RandomSceneWriter {
 public:
  explicit RandomSceneWriter(uint64_t seed) : rng_(seed) {
    scale_ = std::pow(10.0, Uniform(-2, 2));
    if (Uniform(0, 1) < 0.25) {
      offset_[0] = Uniform(-1e6, 1e6);
      offset_[1] = Uniform(-2e5, 2e5);
      offset_[2] = Uniform(-1e6, 1e6);
    }
  }

  std::string Write(int res = kRes) {
    std::string xml =
        "<scene version=\"3.0.0\">\n<integrator type=\"path\">"
        "<integer name=\"max_depth\" value=\"4\"/></integrator>\n";
    // Camera: from a random direction not too close to the up axis, at a random target.
    double dir[3];
    do {
      for (double& d : dir) d = Uniform(-1, 1);
    } while (std::abs(dir[1]) > 0.8 * Length(dir) || Length(dir) < 0.1);
    const double len = Length(dir);
    double eye[3], target[3];
    for (int i = 0; i < 3; ++i) {
      eye[i] = 4 * dir[i] / len;
      target[i] = Uniform(-0.3, 0.3);
    }
    xml += "<sensor type=\"perspective\"><float name=\"fov\" value=\"" + Num(Uniform(30, 70)) +
           "\"/><transform name=\"to_world\"><lookat origin=\"" + World(eye) + "\" target=\"" +
           World(target) +
           "\" up=\"0, 1, 0\"/></transform>"
           "<sampler type=\"independent\"><integer name=\"sample_count\" value=\"16\"/></sampler>"
           "<film type=\"hdrfilm\"><integer name=\"width\" value=\"" +
           std::to_string(res) + "\"/><integer name=\"height\" value=\"" + std::to_string(res) +
           "\"/><rfilter type=\"box\"/></film></sensor>\n";
    const int shapes = 2 + int(Uniform(0, 6));
    for (int i = 0; i < shapes; ++i) xml += RandomShape();
    if (Uniform(0, 1) < 0.5) {  // a huge floor under everything (1e4 times the scene)
      features_ += 'F';
      xml += "<shape type=\"rectangle\">" + Bsdf() +
             ToWorld(
                 "<scale value=\"1e4\"/><rotate "
                 "x=\"1\" y=\"0\" z=\"0\" angle=\"-90\"/><translate x=\"0\" y=\"-1\" z=\"0\"/>") +
             "</shape>\n";
    }
    // Lights: at least one of point or area; sometimes an environment as well.
    const bool point = Uniform(0, 1) < 0.6, area = !point || Uniform(0, 1) < 0.5;
    if (point) {
      features_ += 'P';
      double p[3];
      for (double& c : p) c = Uniform(-1.5, 1.5);
      const double i = Uniform(0.5, 5) * scale_ * scale_;  // same irradiance at any scale
      xml += "<emitter type=\"point\"><point name=\"position\" value=\"" + World(p) +
             "\"/><rgb name=\"intensity\" value=\"" + Rgb(i) + "\"/></emitter>\n";
    }
    if (area) {
      features_ += 'A';
      xml += "<shape type=\"rectangle\">" + Bsdf() + ToWorld(RandomPlacement(0.1, 0.6)) +
             "<emitter type=\"area\"><rgb name=\"radiance\" value=\"" + Rgb(Uniform(1, 20)) +
             "\"/></emitter></shape>\n";
    }
    if (Uniform(0, 1) < 0.25) {
      features_ += 'E';
      xml += "<emitter type=\"constant\"><rgb name=\"radiance\" value=\"" + Rgb(Uniform(0.1, 1)) +
             "\"/></emitter>\n";
    }
    return xml + "</scene>\n";
  }

  double scale() const { return scale_; }
  const std::string& features() const { return features_; }
  bool far() const { return offset_[0] != 0; }

 private:
  double Uniform(double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng_);
  }
  static double Length(const double* v) {
    return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  }
  static std::string Num(double v) {
    char s[32];
    std::snprintf(s, sizeof(s), "%.17g", v);
    return s;
  }
  std::string World(const double* p) const {
    return Num(p[0] * scale_ + offset_[0]) + ", " + Num(p[1] * scale_ + offset_[1]) + ", " +
           Num(p[2] * scale_ + offset_[2]);
  }
  std::string Rgb(double k) {
    return Num(k * Uniform(0.3, 1)) + ", " + Num(k * Uniform(0.3, 1)) + ", " +
           Num(k * Uniform(0.3, 1));
  }
  std::string Bsdf() {
    return "<bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"" + Rgb(0.9) + "\"/></bsdf>";
  }
  // `local` transform steps, then the scene's scale and offset.
  std::string ToWorld(const std::string& local) const {
    return "<transform name=\"to_world\">" + local + "<scale value=\"" + Num(scale_) +
           "\"/><translate x=\"" + Num(offset_[0]) + "\" y=\"" + Num(offset_[1]) + "\" z=\"" +
           Num(offset_[2]) + "\"/></transform>";
  }
  // A random rotation and a position in [-1, 1]^3, after a scale of sx x sy x sz.
  std::string Placement(double sx, double sy, double sz) {
    return "<scale x=\"" + Num(sx) + "\" y=\"" + Num(sy) + "\" z=\"" + Num(sz) +
           "\"/><rotate x=\"" + Num(Uniform(-1, 1)) + "\" y=\"" + Num(Uniform(-1, 1)) + "\" z=\"" +
           Num(Uniform(0.1, 1)) + "\" angle=\"" + Num(Uniform(0, 360)) + "\"/><translate x=\"" +
           Num(Uniform(-1, 1)) + "\" y=\"" + Num(Uniform(-1, 1)) + "\" z=\"" + Num(Uniform(-1, 1)) +
           "\"/>";
  }
  std::string RandomPlacement(double lo, double hi) {
    return Placement(Uniform(lo, hi), Uniform(lo, hi), Uniform(lo, hi));
  }
  std::string RandomShape() {
    const int kind = int(Uniform(0, 6));
    features_ += "bSlcTd"[kind];  // box, Sphere, sliver, coincident, Tiny, disk
    if (kind == 0) {              // box
      return "<shape type=\"cube\">" + Bsdf() + ToWorld(RandomPlacement(0.05, 0.6)) + "</shape>\n";
    }
    if (kind == 1) {  // sphere, radius 1e-3 to 0.5
      double c[3];
      for (double& v : c) v = Uniform(-1, 1);
      return "<shape type=\"sphere\"><point name=\"center\" value=\"" + World(c) +
             "\"/><float name=\"radius\" value=\"" +
             Num(std::pow(10.0, Uniform(-3, std::log10(0.5))) * scale_) + "\"/>" + Bsdf() +
             "</shape>\n";
    }
    if (kind == 2) {  // sliver: 1e-4 to 1e-3 of its length thin
      const double length = Uniform(0.2, 1);
      return "<shape type=\"rectangle\">" + Bsdf() +
             ToWorld(Placement(length, length * std::pow(10.0, Uniform(-4, -3)), 1)) + "</shape>\n";
    }
    if (kind == 3) {  // coincident faces: two rectangles on the same plane, different colours
      const std::string where = ToWorld(RandomPlacement(0.2, 0.8));
      return "<shape type=\"rectangle\">" + Bsdf() + where +
             "</shape>\n<shape type=\"rectangle\">" + Bsdf() + where + "</shape>\n";
    }
    if (kind == 4) {  // tiny: 1e-5 to 1e-4
      const double s = std::pow(10.0, Uniform(-5, -4));
      return "<shape type=\"rectangle\">" + Bsdf() + ToWorld(Placement(s, s, 1)) + "</shape>\n";
    }
    return "<shape type=\"disk\">" + Bsdf() + ToWorld(RandomPlacement(0.1, 0.8)) + "</shape>\n";
  }

  std::mt19937_64 rng_;
  std::string features_;
  double scale_ = 1;
  double offset_[3] = {0, 0, 0};
};

// Every pixel finite and non-negative, and no non-finite sample counted.
void ExpectClean(const RenderOutput& out, const std::string& what) {
  EXPECT_EQ(out.stats.nonfinite_pixels, 0) << what;
  EXPECT_EQ(out.stats.counters.nonfinite_samples, 0u) << what;
  long bad = 0;
  for (const Vec3& p : out.image.pixels)
    for (int c = 0; c < 3; ++c) bad += !(std::isfinite(p[c]) && p[c] >= 0);
  EXPECT_EQ(bad, 0) << what << ": pixels that are NaN, infinite or negative";
}

TEST(RandomScenePropertyTest, NoNanNoInfinityNoNegativeAndIrrcacheMeanMatchesPath) {
  int far = 0, lit = 0, rare = 0;
  for (int i = 0; i < kScenes; ++i) {
    RandomSceneWriter writer(1000 + i);
    const bool coarse =
        std::find(std::begin(kCoarseScenes), std::end(kCoarseScenes), i) != std::end(kCoarseScenes);
    const std::string xml = writer.Write(coarse ? kCoarseRes : kRes);
    far += writer.far();
    const std::string what = "scene " + std::to_string(i) + ":\n" + xml;
    const absl::StatusOr<SceneDesc> desc = LoadSceneString(xml, "random.xml", LoadOptions{});
    if (!desc.ok()) {
      ADD_FAILURE() << desc.status() << "\n" << what;
      continue;
    }
    const LoadedScene s = BuildLoaded(desc);
    if (!s.scene) {
      ADD_FAILURE() << what;
      continue;
    }
    const RenderOutput path_a = RenderWith(s, "path", kSpp, 1, 0, false);
    const RenderOutput path_b = RenderWith(s, "path", kSpp, 2, 0, false);
    const RenderOutput irr_a = RenderWith(s, "irrcache", kSpp, 3, 0, false);
    const RenderOutput irr_b = RenderWith(s, "irrcache", kSpp, 4, 0, false);
    for (const RenderOutput* out : {&path_a, &path_b, &irr_a, &irr_b}) ExpectClean(*out, what);
    ImageMean path = MeanOfTwo(path_a.image, path_b.image);
    const ImageMean irr = MeanOfTwo(irr_a.image, irr_b.image);
    if (std::find(std::begin(kHeavyTailedScenes), std::end(kHeavyTailedScenes), i) !=
        std::end(kHeavyTailedScenes))
      continue;
    if (path.mean == 0 && irr.mean > 0) {
      path = MeanOfTwo(RenderWith(s, "path", kRareLightSpp, 5, 0, false).image,
                       RenderWith(s, "path", kRareLightSpp, 6, 0, false).image);
      ++rare;
    }
    lit += path.mean > 0;
    const double accuracy = SettingsForScene(s.desc, "irrcache")->irrcache.accuracy;
    const double bound = 4 * std::hypot(path.std_err, irr.std_err) + accuracy * path.mean;
    EXPECT_LE(std::abs(irr.mean - path.mean), bound)
        << "scene " << i << " [" << writer.features() << "] scale " << writer.scale()
        << (writer.far() ? " far" : "") << ": path mean " << path.mean << " +- " << path.std_err
        << ", irrcache " << irr.mean << " +- " << irr.std_err;
  }
  std::printf(
      "MEASURED %d scenes, %d far from the origin, %d with light reaching the camera, %d where "
      "path needed %d spp to find it\n",
      kScenes, far, lit, rare, kRareLightSpp);
  // The generator must produce what the test claims to cover.
  EXPECT_GE(far, kScenes / 8);
  EXPECT_GE(lit, kScenes * 3 / 4);
}

}  // namespace
}  // namespace irfarm

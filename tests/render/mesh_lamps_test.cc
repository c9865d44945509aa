// Lamps that are triangle meshes (a ceiling disk by a wall, an upright tube by another), whose
// triangles the light tree picks (render/light_tree.h), against Mitsuba 3 on
// tests/data/scenes/mesh-lamps (reference: Mitsuba 3.9.1 at 16384 spp, make_reference.py there).
// irfarm's `path` and `irrcache` at 256 spp must be within Mitsuba's own error at 256 spp against
// that reference (the largest of 8 seeds: reference.json). Variants that light the room
// differently, by as much as a lost or doubled share of a lamp's triangles would, must fail it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "render_test_util.h"

namespace irfarm {
namespace {

constexpr char kScene[] = "mesh-lamps";

TEST(MeshLampsTest, PathAndIrrcacheMatchMitsubaWithinItsNoise) {
  ExpectWithinMitsuba256Spp(kScene, BuildLoaded(LoadSceneFile(TestScenePath(kScene), {})));
}

TEST(MeshLampsTest, ALampLitWronglyIsFarFromMitsuba) {
  ExpectFarFromMitsuba256Spp(kScene, "tube at 0.75 of its radiance",
                             LoadVariant(kScene, R"(value="30,32,36")", R"(value="22.5,24,27")"));
  ExpectFarFromMitsuba256Spp(kScene, "disk at half its radiance",
                             LoadVariant(kScene, R"(value="12,11,9.5")", R"(value="6,5.5,4.75")"));
}

// --target-error on a room whose cache error is its records' noise (the patches of wall and
// ceiling the lamps light from 4 and 7 cm away, found by few of a record's rays): the refinement's
// checks measure the wider camera lookups lower, and the render takes them (stats
// lookup_factor), landing within issue 6's band [E/2, 2E] of the reference (widened by the
// reference's own error). With Ward's rule throughout it ended at the 10x-work stop with the
// cache above its share (estimate 5.2e-3). One thread: one image in every run (seed 5: 4.2e-3).
TEST(MeshLampsTest, TargetErrorWidensTheLookupsWhereRecordsAreNoisy) {
  const LoadedScene s = BuildLoaded(LoadSceneFile(TestScenePath(kScene), {}));
  RenderSettings settings = *SettingsForScene(s.desc, "irrcache");
  settings.seed = 5;
  settings.threads = 1;
  settings.target_error = 4e-3;
  settings.adaptive = true;
  const RenderOutput out = Render(*s.scene, settings);
  EXPECT_FLOAT_EQ(out.stats.lookup_factor, IrrcacheSettings{}.lookup_factor);
  const double err = CompareImages(out.image, FullReference(kScene)).relmse;
  RecordProperty("relmse", std::to_string(err));
  EXPECT_GT(err, 0.5 * settings.target_error - ReferenceError(kScene));
  EXPECT_LT(err, 2 * settings.target_error + ReferenceError(kScene));
}

// A lamp mirrored by its to_world (a cube scaled by -0.2 along x: the same cube, its triangles'
// winding reversed while its vertex normals still point out) lights the floor as the unmirrored
// one does. It emits on its shading normals' side (Scene::Emitted, as Mitsuba 3), so its light
// samples must face that side too; before, they faced the winding's side, inward, and the lamp
// seen by the camera gave the floor the light of its far faces only.
TEST(MeshLampsTest, AMirroredLampLightsAsTheSameLampUnmirrored) {
  const auto lamp = [](const char* scale) {
    return BuildLoaded(LoadSceneString(std::string(R"(<scene version="3.0.0">
  <sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/>
    <integer name="height" value="8"/></film></sensor>
  <shape type="cube">
    <transform name="to_world"><scale )") + scale +
                                           R"(/><translate z="1"/></transform>
    <emitter type="area"><rgb name="radiance" value="4"/></emitter>
  </shape>
</scene>
)",
                                       "lamp.xml", {}));
  };
  const LoadedScene plain = lamp(R"(x="0.2" y="0.2" z="0.2")");
  const LoadedScene mirrored = lamp(R"(x="-0.2" y="0.2" z="0.2")");
  ASSERT_TRUE(plain.scene && mirrored.scene);
  const Vec3 up(0, 0, 1);
  for (const Vec3& p : {Vec3(0, 0, 0), Vec3(0.7f, 0.1f, 0.3f), Vec3(-1, 0.5f, 1.1f)}) {
    const float w = plain.scene->light_sampler().Weight(0, p, up);
    EXPECT_GT(w, 0);
    EXPECT_NEAR(mirrored.scene->light_sampler().Weight(0, p, up), w, 1e-4f * w) << p.x;
    // The unoccluded irradiance its samples estimate (Le cos / pdf), each within 4 standard
    // errors of the other (the estimates' own noise, from 16384 samples each).
    constexpr int kN = 16384;
    double mean[2], var[2];
    for (int k = 0; k < 2; ++k) {
      const LightSampler& ls = (k == 0 ? plain : mirrored).scene->light_sampler();
      Rng rng(5, 6 + k);
      double sum = 0, sum2 = 0;
      for (int i = 0; i < kN; ++i) {
        LightSample s;
        const float u2 = rng.Next(), u3 = rng.Next();
        const double v = ls.SampleOne(0, p, up, u2, u3, &s)
                             ? Luminance(s.value) * std::max(0.0f, Dot(s.wi, up))
                             : 0.0;
        sum += v;
        sum2 += v * v;
      }
      mean[k] = sum / kN;
      var[k] = (sum2 / kN - mean[k] * mean[k]) / kN;
    }
    std::printf("MEASURED at (%g, %g, %g): E %.4g plain, %.4g mirrored (std. errors %.2g, %.2g)\n",
                p.x, p.y, p.z, mean[0], mean[1], std::sqrt(var[0]), std::sqrt(var[1]));
    EXPECT_GT(mean[0], 0);
    EXPECT_NEAR(mean[1], mean[0], 4 * std::sqrt(var[0] + var[1])) << p.x;
  }
  // The camera-visible side agrees: a ray up from the floor meets an emitting face.
  SurfaceHit hit;
  ASSERT_TRUE(mirrored.scene->Intersect(Ray{Vec3(0, 0, 0), up, INFINITY}, &hit));
  EXPECT_GT(Luminance(mirrored.scene->Emitted(hit, -up)), 0);
}

}  // namespace
}  // namespace irfarm

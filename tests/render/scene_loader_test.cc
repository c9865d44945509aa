// Tests for the XML scene loader and the mesh loader: every error kind of docs/scene-format.md
// ("What a bad scene gets") with its PATH:LINE, transforms, the camera, $name substitution,
// materials, OBJ/PLY meshes, degenerate triangles, and every scene under IRFARM_TEST_DATA/scenes.
// Scenes are given as strings; meshes are written to a temporary folder.

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "render/camera.h"
#include "render/emitters/registry.h"
#include "render/mesh_loader.h"
#include "render/scene_loader.h"
#include "render/shapes/registry.h"
#include "render/textures/registry.h"

#include "absl/strings/str_join.h"
#include "render/bsdfs/registry.h"

#ifndef IRFARM_TEST_DATA
#error "IRFARM_TEST_DATA must name the test data folder"
#endif

namespace irfarm {
namespace {

namespace fs = std::filesystem;

constexpr char kSensor[] = R"(  <sensor type="perspective">
    <float name="fov" value="45"/>
    <film type="hdrfilm">
      <integer name="width" value="64"/>
      <integer name="height" value="48"/>
      <rfilter type="box"/>
    </film>
  </sensor>
)";

// A scene whose `body` starts on line 2, followed by a valid sensor.
std::string Wrap(const std::string& body) {
  return "<scene version=\"3.0.0\">\n" + body + kSensor + "</scene>\n";
}

absl::StatusOr<SceneDesc> Load(const std::string& body, const std::string& path = "scene.xml",
                               const LoadOptions& options = {}) {
  return LoadSceneString(Wrap(body), path, options);
}

// Checks a one-line error message that starts with `prefix` ("PATH:LINE:") and contains `part`.
void ExpectError(const absl::StatusOr<SceneDesc>& result, const std::string& prefix,
                 const std::string& part,
                 absl::StatusCode code = absl::StatusCode::kInvalidArgument) {
  ASSERT_FALSE(result.ok()) << "expected an error containing: " << part;
  const std::string message(result.status().message());
  EXPECT_EQ(result.status().code(), code) << message;
  EXPECT_EQ(message.rfind(prefix, 0), 0u)
      << "message: " << message << "\nexpected prefix: " << prefix;
  EXPECT_NE(message.find(part), std::string::npos) << "message: " << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
}

// A fresh folder for one test's scene and meshes.
std::string MakeDir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("scene_loader_test_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir / "meshes");
  return dir.string();
}

void WriteFile(const std::string& path, const std::string& data) {
  std::ofstream(path, std::ios::binary) << data;
}

void ExpectNear(const Vec3& a, const Vec3& b, float tolerance = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, tolerance);
  EXPECT_NEAR(a.y, b.y, tolerance);
  EXPECT_NEAR(a.z, b.z, tolerance);
}

Vec3 Column(const Mat4& m, int j) {
  return Vec3(float(m.m[0][j]), float(m.m[1][j]), float(m.m[2][j]));
}

// The center of a unit sphere after the given <transform> children.
Vec3 SphereCenterAfter(const std::string& transform_children) {
  const auto scene = Load("<shape type=\"sphere\"><transform name=\"to_world\">" +
                          transform_children + "</transform></shape>\n");
  EXPECT_TRUE(scene.ok()) << scene.status();
  return scene.ok() ? scene->shapes.at(0).center : Vec3(NAN);
}

// ---------------------------------------------------------------- errors, one per kind

TEST(SceneLoaderErrorTest, MalformedXml) {
  const auto r = LoadSceneString("<scene version=\"3.0.0\">\n  <shape type=\"cube\">\n</scene>\n",
                                 "bad.xml", {});
  ExpectError(r, "bad.xml:3:", "malformed XML");
}

TEST(SceneLoaderErrorTest, MissingSceneFile) {
  const std::string path = ::testing::TempDir() + "/no/such/scene.xml";
  ExpectError(LoadSceneFile(path, {}), path + ":0:", "cannot open", absl::StatusCode::kNotFound);
}

TEST(SceneLoaderErrorTest, MissingMeshFile) {
  const std::string dir = MakeDir("missing_mesh");
  const auto r = Load(R"(  <shape type="obj">
    <string name="filename" value="meshes/none.obj"/>
  </shape>
)",
                      dir + "/scene.xml");
  ExpectError(r, dir + "/scene.xml:3:", "'meshes/none.obj' not found", absl::StatusCode::kNotFound);
}

TEST(SceneLoaderErrorTest, MissingTextureFile) {
  const std::string dir = MakeDir("missing_texture");
  const auto r = Load(R"(  <bsdf type="diffuse" id="b">
    <texture type="bitmap" name="reflectance">
      <string name="filename" value="textures/none.png"/>
    </texture>
  </bsdf>
)",
                      dir + "/scene.xml");
  ExpectError(r, dir + "/scene.xml:4:", "'textures/none.png' not found",
              absl::StatusCode::kNotFound);
}

TEST(SceneLoaderErrorTest, MalformedNumber) {
  ExpectError(Load("  <shape type=\"sphere\">\n    <float name=\"radius\" value=\"1.2.3\"/>\n"
                   "  </shape>\n"),
              "scene.xml:3:", "malformed number '1.2.3' in <float name=\"radius\">");
  ExpectError(Load("  <shape type=\"sphere\">\n    <transform name=\"to_world\">\n"
                   "      <translate x=\"abc\"/>\n    </transform>\n  </shape>\n"),
              "scene.xml:4:", "malformed number 'abc' in attribute 'x' of <translate>");
  ExpectError(
      Load("  <bsdf type=\"diffuse\">\n    <rgb name=\"reflectance\" value=\"0.5, x, 0.5\"/>\n"
           "  </bsdf>\n"),
      "scene.xml:3:", "malformed number 'x'");
  ExpectError(Load("  <integrator type=\"path\">\n    <integer name=\"max_depth\" value=\"2.5\"/>\n"
                   "  </integrator>\n"),
              "scene.xml:3:", "malformed integer '2.5'");
}

TEST(SceneLoaderErrorTest, NonFiniteNumber) {
  ExpectError(Load("  <shape type=\"sphere\">\n    <float name=\"radius\" value=\"nan\"/>\n"
                   "  </shape>\n"),
              "scene.xml:3:", "non-finite number 'nan'");
  ExpectError(
      Load("  <bsdf type=\"diffuse\">\n    <rgb name=\"reflectance\" value=\"1, inf, 0\"/>\n"
           "  </bsdf>\n"),
      "scene.xml:3:", "non-finite number 'inf'");
  ExpectError(Load("  <shape type=\"sphere\">\n    <point name=\"center\" value=\"0, 1e999, 0\"/>\n"
                   "  </shape>\n"),
              "scene.xml:3:", "non-finite number '1e999'");
}

// Finite numbers a float cannot hold, and a sign after a '+', are refused (a review: a sphere of
// radius 1e39 vanished and a lamp of radiance 1e39 was black, silently; "+-2" read as -2).
TEST(SceneLoaderErrorTest, NumbersBeyondAFloatOrWithTwoSigns) {
  ExpectError(
      Load("  <shape type=\"sphere\">\n    <float name=\"radius\" value=\"1e39\"/>\n"
           "  </shape>\n"),
      "scene.xml:3:", "value 1e+39 in <float name=\"radius\"> is beyond the range of a float");
  ExpectError(
      Load("  <bsdf type=\"diffuse\">\n    <rgb name=\"reflectance\" value=\"0.5, -1e39, 0\"/>\n"
           "  </bsdf>\n"),
      "scene.xml:3:", "beyond the range of a float");
  ExpectError(Load("  <shape type=\"sphere\">\n    <point name=\"center\" value=\"0, 4e38, 0\"/>\n"
                   "  </shape>\n"),
              "scene.xml:3:", "beyond the range of a float");
  EXPECT_TRUE(Load("  <shape type=\"sphere\">\n    <float name=\"radius\" value=\"3e38\"/>\n"
                   "  </shape>\n")
                  .ok());
  ExpectError(Load("  <shape type=\"sphere\">\n    <float name=\"radius\" value=\"+-2\"/>\n"
                   "  </shape>\n"),
              "scene.xml:3:", "malformed number '+-2'");
  ExpectError(Load("  <integrator type=\"path\">\n    <integer name=\"max_depth\" value=\"+-2\"/>\n"
                   "  </integrator>\n"),
              "scene.xml:3:", "malformed integer '+-2'");
  EXPECT_TRUE(Load("  <shape type=\"sphere\">\n    <float name=\"radius\" value=\"+2\"/>\n"
                   "  </shape>\n")
                  .ok());
}

// A rotation axis of any finite length is a direction: (1e-200, 0, 0) made a NaN matrix (a camera
// of it crashed in Embree) and (1e200, 0, 0) a matrix that halved the shape.
TEST(SceneLoaderTest, RotationAxesOfAnyLengthAreDirections) {
  for (const char* x : {"1", "1e-200", "1e200", "3e-30"}) {
    const Vec3 c = SphereCenterAfter(std::string("<translate y=\"2\"/><rotate x=\"") + x +
                                     "\" angle=\"90\"/>");
    ExpectNear(c, Vec3(0, 0, 2));
  }
}

// A to_world that flattens a flat shape along its normal (scale z = 0 on a rectangle, then a
// rotation) leaves it a rectangle; its normals now turn with it (the inverse transpose does not
// exist there, and the identity was used: normals lying in the surface).
TEST(SceneLoaderTest, NormalsOfAShapeFlattenedAlongItsNormalTurnWithIt) {
  const auto normal_after = [](const std::string& transform) {
    const auto scene = Load("<shape type=\"rectangle\"><transform name=\"to_world\">" + transform +
                            "</transform></shape>\n");
    EXPECT_TRUE(scene.ok()) << scene.status();
    if (!scene.ok() || scene->shapes.at(0).mesh.normals.empty()) return Vec3(NAN);
    return scene->shapes.at(0).mesh.normals[0];
  };
  const Vec3 expected = normal_after("<rotate x=\"1\" angle=\"-60\"/>");
  ExpectNear(expected, Vec3(0, std::sin(kPi / 3), std::cos(kPi / 3)));
  ExpectNear(normal_after("<scale x=\"1\" y=\"1\" z=\"0\"/><rotate x=\"1\" angle=\"-60\"/>"),
             expected);
  // A mirror keeps the inverse transpose's direction (the winding is reversed separately).
  ExpectNear(normal_after("<scale x=\"-1\" y=\"1\" z=\"1\"/><rotate x=\"1\" angle=\"-60\"/>"),
             expected);
}

// A film of more pixels than a render can hold is refused at its line (60000 x 60000 ended in an
// uncaught bad_alloc).
TEST(SceneLoaderErrorTest, AFilmTooLargeIsRefused) {
  const std::string scene =
      "<scene version=\"3.0.0\">\n<sensor type=\"perspective\">\n<film type=\"hdrfilm\">\n"
      "<integer name=\"width\" value=\"60000\"/>\n<integer name=\"height\" value=\"60000\"/>\n"
      "</film>\n</sensor>\n</scene>\n";
  ExpectError(LoadSceneString(scene, "big.xml", {}),
              "big.xml:4:", "film of 60000 x 60000 pixels is larger than");
}

TEST(SceneLoaderErrorTest, NegativeOrZeroRadius) {
  ExpectError(Load("  <shape type=\"sphere\">\n    <float name=\"radius\" value=\"-0.5\"/>\n"
                   "  </shape>\n"),
              "scene.xml:3:", "sphere radius must be positive, got -0.5");
  ExpectError(Load("\n  <shape type=\"sphere\">\n    <float name=\"radius\" value=\"0\"/>\n"
                   "  </shape>\n"),
              "scene.xml:4:", "sphere radius must be positive, got 0");
}

TEST(SceneLoaderErrorTest, ObjIndexOutOfRange) {
  const std::string dir = MakeDir("obj_index");
  WriteFile(dir + "/meshes/bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n");
  const auto r = Load(R"(  <bsdf type="diffuse" id="b"/>
  <shape type="obj">
    <string name="filename" value="meshes/bad.obj"/>
  </shape>
)",
                      dir + "/scene.xml");
  ExpectError(r, dir + "/scene.xml:3:", "bad.obj:5: vertex index 9 out of range (the file has 3");
  // Relative indices are checked too, and so are vt / vn.
  WriteFile(dir + "/meshes/bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
  ExpectError(Load("  <shape type=\"obj\">\n    <string name=\"filename\" "
                   "value=\"meshes/bad.obj\"/>\n  </shape>\n",
                   dir + "/scene.xml"),
              dir + "/scene.xml:2:", "bad.obj:4: relative index -4 out of range");
  WriteFile(dir + "/meshes/bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n");
  ExpectError(Load("  <shape type=\"obj\">\n    <string name=\"filename\" "
                   "value=\"meshes/bad.obj\"/>\n  </shape>\n",
                   dir + "/scene.xml"),
              dir + "/scene.xml:2:", "bad.obj:5: normal index 2 out of range");
}

// OBJ values beyond a float are refused as PLY's are; a PLY count beyond 64 bits and a
// fractional ASCII index are refused, named (a review: inf vertices dropped as degenerate; a
// count read as 0; 1.7 read as 1).
TEST(SceneLoaderErrorTest, MeshValuesAFloatCannotHoldOrAnIndexCannotBe) {
  const std::string dir = MakeDir("mesh_ranges");
  const auto load = [&](const std::string& type, const std::string& file) {
    return Load("  <shape type=\"" + type + "\">\n    <string name=\"filename\" value=\"meshes/" +
                    file + "\"/>\n  </shape>\n",
                dir + "/scene.xml");
  };
  WriteFile(dir + "/meshes/big.obj", "v 0 0 0\nv 1 0 0\nv 0 1 1e39\nf 1 2 3\n");
  ExpectError(load("obj", "big.obj"),
              dir + "/scene.xml:2:", "big.obj:3: value '1e39' is beyond the range of a float");
  WriteFile(dir + "/meshes/count.ply",
            "ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\nproperty float x\n"
            "end_header\n");
  ExpectError(load("ply", "count.ply"),
              dir + "/scene.xml:2:", "count.ply:3: malformed or out-of-range element count");
  WriteFile(dir + "/meshes/frac.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
            "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1.7 2\n");
  ExpectError(load("ply", "frac.ply"),
              dir + "/scene.xml:2:", "frac.ply: face 0: vertex index 1.7 is not a whole number");
}

TEST(SceneLoaderErrorTest, PlyIndexOutOfRange) {
  const std::string dir = MakeDir("ply_index");
  WriteFile(dir + "/meshes/bad.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
            "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 3\n");
  const auto r = Load(R"(  <shape type="ply">
    <string name="filename" value="meshes/bad.ply"/>
  </shape>
)",
                      dir + "/scene.xml");
  ExpectError(r, dir + "/scene.xml:2:", "bad.ply: face 1: vertex index 3 out of range");

  // Found by the fuzzer: a list count of 4294967295 (a uint count) was cast to int.
  const auto load_with_body = [&](const std::string& count_type, const std::string& body) {
    WriteFile(dir + "/meshes/bad.ply",
              "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1\nproperty list " +
                  count_type + " int vertex_indices\nend_header\n" + body);
    return Load(
        "  <shape type=\"ply\">\n    <string name=\"filename\" "
        "value=\"meshes/bad.ply\"/>\n  </shape>\n",
        dir + "/scene.xml");
  };
  ExpectError(load_with_body("uint", "0 0 0\n1 0 0\n0 1 0\n4294967295 0 1 2\n"),
              dir + "/scene.xml:2:", "bad.ply: face 0: list of 4.29497e+09 entries");
  ExpectError(load_with_body("uint", "0 0 0\n1 0 0\n0 1 0\n2.5 0 1 2\n"),
              dir + "/scene.xml:2:", "bad.ply: face 0: list of 2.5 entries");
  ExpectError(load_with_body("uchar", "0 0 0\n1 0 0\n0 1e300 0\n3 0 1 2\n"),
              dir + "/scene.xml:2:", "bad.ply: vertex 2: y = 1e+300 is not a finite 32-bit float");
  ExpectError(load_with_body("uchar", "0 0 0\n1 0 0\n0 1 0\n3 0 1 1e300\n"),
              dir + "/scene.xml:2:", "bad.ply: face 0: vertex index 1e+300 out of range");
  // An ASCII element without properties and a count of 1.8e19 looped for ever (a review's
  // finding); one with properties and more items than the file has bytes is refused at once.
  WriteFile(dir + "/meshes/bad.ply",
            "ply\nformat ascii 1.0\nelement junk 18000000000000000000\nelement vertex 3\n"
            "property float x\nproperty float y\nproperty float z\nelement face 1\n"
            "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  EXPECT_TRUE(Load("  <shape type=\"ply\">\n    <string name=\"filename\" "
                   "value=\"meshes/bad.ply\"/>\n  </shape>\n",
                   dir + "/scene.xml")
                  .ok());
  WriteFile(dir + "/meshes/bad.ply",
            "ply\nformat ascii 1.0\nelement vertex 18000000000000000000\nproperty float x\n"
            "property float y\nproperty float z\nend_header\n0 0 0\n");
  ExpectError(Load("  <shape type=\"ply\">\n    <string name=\"filename\" "
                   "value=\"meshes/bad.ply\"/>\n  </shape>\n",
                   dir + "/scene.xml"),
              dir + "/scene.xml:2:", "element vertex: file is truncated or malformed");
}

// Elements nested past 64 deep are refused at the first one past it: the loader reads nested
// elements recursively, and 5000 nested masks (125 kB, an upload to the coordinator) overflowed
// its stack.
TEST(SceneLoaderErrorTest, DeepNestingIsRefused) {
  std::string xml;
  for (int i = 0; i < 10000; ++i) xml += "<bsdf type=\"mask\">";
  for (int i = 0; i < 10000; ++i) xml += "</bsdf>";
  ExpectError(Load("  " + xml + "\n"), "scene.xml:2:", "elements nested more than 64 deep");
}

TEST(SceneLoaderErrorTest, BlendAndNullBsdfs) {
  ASSERT_TRUE(Load("  <bsdf type=\"blendbsdf\" id=\"b\"><float name=\"weight\" value=\"0.3\"/>"
                   "<bsdf type=\"diffuse\"/><bsdf type=\"conductor\"/></bsdf>\n"
                   "  <shape type=\"sphere\"><bsdf type=\"null\"/></shape>\n")
                  .ok());
  ExpectError(Load("  <bsdf type=\"blendbsdf\"><bsdf type=\"diffuse\"/></bsdf>\n"),
              "scene.xml:2:", "blendbsdf needs exactly two nested bsdfs");
  // A null-BSDF lamp loads (RenderPropertiesTest.NullBsdfLampsAreSeenAndPassedThrough renders it).
  EXPECT_TRUE(Load("  <shape type=\"sphere\"><bsdf type=\"null\"/>\n"
                   "    <emitter type=\"area\"/></shape>\n")
                  .ok());
}

// shapegroup / instance (Blender's exporter writes them for instanced objects): each instance
// places a copy of the group's shapes by its to_world. (A render of two instances of a sphere
// and a gold cube agrees with Mitsuba 3.9.1: relMSE 3.7e-5 path, 2.1e-4 irrcache.)
TEST(SceneLoaderTest, InstancesCopyTheirShapeGroup) {
  const auto scene = Load(R"(  <shape type="shapegroup" id="g">
    <shape type="sphere"><point name="center" value="0, 0, 0.4"/>
      <float name="radius" value="0.4"/></shape>
    <shape type="cube"><transform name="to_world"><scale value="0.2"/></transform></shape>
  </shape>
  <shape type="instance"><ref id="g"/>
    <transform name="to_world"><translate x="-1.2"/></transform></shape>
  <shape type="instance"><ref id="g"/>
    <transform name="to_world"><rotate z="1" angle="60"/><scale value="1.3"/>
      <translate x="1" y="0.5"/></transform></shape>
)");
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->shapes.size(), 4u);
  ExpectNear(scene->shapes[0].center, Vec3(-1.2f, 0, 0.4f));
  EXPECT_NEAR(scene->shapes[0].radius, 0.4f, 1e-6f);
  ExpectNear(scene->shapes[2].center, Vec3(1, 0.5f, 0.52f));
  EXPECT_NEAR(scene->shapes[2].radius, 0.52f, 1e-6f);
  // The cube's corner (0.2, 0.2, 0.2) through the second instance.
  const float c = 0.2f * 1.3f, s60 = std::sin(60 * 3.14159265f / 180), c60 = 0.5f;
  bool found = false;
  for (const Vec3& v : scene->shapes[3].mesh.positions)
    found |= Length(v - Vec3(1 + c * (c60 - s60), 0.5f + c * (s60 + c60), c)) < 1e-5f;
  EXPECT_TRUE(found);

  // A mirrored instance keeps its front, as Mitsuba moves an instance's normals with to_world's
  // normal transform: the rectangle's +z, through scale x -1, is still +z (its triangles' winding
  // gave -z before).
  const auto mirrored = Load(R"(  <shape type="shapegroup" id="g"><shape type="rectangle"/></shape>
  <shape type="instance"><ref id="g"/><transform name="to_world"><scale x="-1"/></transform></shape>
)");
  ASSERT_TRUE(mirrored.ok()) << mirrored.status();
  const TriangleMesh& m = mirrored->shapes.at(0).mesh;
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    const Vec3 a = m.positions[m.indices[t]], b = m.positions[m.indices[t + 1]],
               c = m.positions[m.indices[t + 2]];
    EXPECT_GT(Cross(b - a, c - a).z, 0.0f) << "triangle " << t / 3;
  }
  ExpectError(Load("  <shape type=\"shapegroup\" id=\"g\"><shape type=\"sphere\">\n"
                   "    <emitter type=\"area\"/></shape></shape>\n"),
              "scene.xml:3:", "a shape in a shapegroup cannot emit");
  ExpectError(Load("  <shape type=\"instance\"/>\n"),
              "scene.xml:2:", "an instance needs exactly one <ref> to a shapegroup");
}

TEST(SceneLoaderErrorTest, UnknownPluginType) {
  const auto r = Load("  <bsdf type=\"measured\" id=\"x\"/>\n");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "scene.xml:2: unknown bsdf type 'measured' (supported: " +
                                      absl::StrJoin(BsdfPluginNames(), ", ") + ")");
  const auto shape = Load("\n  <shape type=\"mesh\"/>\n");
  ASSERT_FALSE(shape.ok());
  EXPECT_EQ(shape.status().message(), "scene.xml:3: unknown shape type 'mesh' (supported: " +
                                          absl::StrJoin(ShapePluginNames(), ", ") +
                                          ", shapegroup, instance)");
  const auto texture = Load("  <texture type=\"noise\" id=\"t\"/>\n");
  ASSERT_FALSE(texture.ok());
  EXPECT_EQ(texture.status().message(), "scene.xml:2: unknown texture type 'noise' (supported: " +
                                            absl::StrJoin(TexturePluginNames(), ", ") + ")");
  EXPECT_EQ(absl::StrJoin(TexturePluginNames(), ","), "bitmap,checkerboard");
  ExpectError(Load("  <texture type=\"checkerboard\" id=\"t\">\n"
                   "    <string name=\"filter_type\" value=\"nearest\"/>\n  </texture>\n"),
              "scene.xml:3:", "unknown parameter 'filter_type' for texture 'checkerboard'");
  const auto emitter = Load("  <emitter type=\"sky\"/>\n");
  ASSERT_FALSE(emitter.ok());
  EXPECT_EQ(emitter.status().message(), "scene.xml:2: unknown emitter type 'sky' (supported: " +
                                            absl::StrJoin(EmitterPluginNames(), ", ") + ")");
  ExpectError(Load("  <integrator type=\"bdpt\"/>\n"), "scene.xml:2:",
              "unknown integrator type 'bdpt' (supported: path, irrcache, volpath, prbvolpath, "
              "prb, direct)");
  // Without media (irfarm refuses them) Mitsuba's volpath and prb render path's image.
  const auto volpath = Load(
      "  <integrator type=\"volpath\"><integer name=\"max_depth\" "
      "value=\"7\"/></integrator>\n");
  ASSERT_TRUE(volpath.ok()) << volpath.status();
  EXPECT_EQ(volpath->integrator.type, "path");
  EXPECT_EQ(volpath->integrator.max_depth, 7);
  ExpectError(Load("  <medium type=\"homogeneous\"/>\n"),
              "scene.xml:2:", "unknown element <medium>");
}

TEST(SceneLoaderErrorTest, UnknownParameter) {
  ExpectError(
      Load("  <bsdf type=\"diffuse\">\n    <rgb name=\"reflectnce\" value=\"0.5\"/>\n"
           "  </bsdf>\n"),
      "scene.xml:3:", "unknown parameter 'reflectnce' for bsdf 'diffuse' (supported: reflectance)");
  ExpectError(Load("  <shape type=\"cube\">\n    <float name=\"radius\" value=\"1\"/>\n"
                   "  </shape>\n"),
              "scene.xml:3:", "unknown parameter 'radius' for shape 'cube'");
  ExpectError(Load("  <bsdf type=\"diffuse\">\n    <float name=\"reflectance\" value=\"0.5\" "
                   "extra=\"1\"/>\n  </bsdf>\n"),
              "scene.xml:3:", "unexpected attribute 'extra'");
  // A parameter of the wrong type is an error as well.
  ExpectError(Load("  <shape type=\"sphere\">\n    <string name=\"radius\" value=\"1\"/>\n"
                   "  </shape>\n"),
              "scene.xml:3:", "parameter 'radius' of shape 'sphere' must be <float> or <integer>");
}

TEST(SceneLoaderErrorTest, FileOutsideSceneFolder) {
  const std::string dir = MakeDir("outside");
  const auto load = [&](const std::string& filename) {
    return Load("  <shape type=\"obj\">\n    <string name=\"filename\" value=\"" + filename +
                    "\"/>\n  </shape>\n",
                dir + "/scene.xml");
  };
  ExpectError(load("../outside.obj"), dir + "/scene.xml:3:", "leaves the scene folder");
  ExpectError(load("meshes/../../outside.obj"), dir + "/scene.xml:3:", "leaves the scene folder");
  ExpectError(load("/etc/hosts"), dir + "/scene.xml:3:", "is absolute");
}

TEST(SceneLoaderErrorTest, Spectrum) {  // values are read: spectrum_test.cc
  ExpectError(
      Load("  <bsdf type=\"diffuse\">\n    <spectrum name=\"reflectance\" filename=\"a.spd\"/>\n"
           "  </bsdf>\n"),
      "scene.xml:3:", "spectrum files (filename=)");
  ExpectError(Load("  <spectrum id=\"s\" value=\"0.5\"/>\n"),
              "scene.xml:2:", "<spectrum> outside the object that uses it");
}

TEST(SceneLoaderErrorTest, UndefinedParameter) {
  ExpectError(
      Load("  <integrator type=\"path\">\n    <integer name=\"max_depth\" value=\"$depth\"/>\n"
           "  </integrator>\n"),
      "scene.xml:3:", "undefined parameter '$depth'");
}

// $name substitution is bounded: a 1 MiB <default> named 2^20 times in one attribute (a 2 MiB
// upload) expanded to 1 TiB and the process died (bad_alloc); many attributes of 1 MiB each are
// bounded together. A few references to a long value still load.
TEST(SceneLoaderErrorTest, ParameterExpansionIsBounded) {
  const std::string big = "0.5" + std::string((size_t(1) << 20) - 3, '0');  // 1 MiB: 0.5
  std::string refs;
  for (int i = 0; i < (1 << 20); ++i) refs += "$x";
  ExpectError(Load("  <default name=\"x\" value=\"" + big +
                   "\"/>\n  <integrator type=\"path\">\n    <integer name=\"max_depth\" "
                   "value=\"" +
                   refs + "\"/>\n  </integrator>\n"),
              "scene.xml:4:", "expands past the limit");
  // 300 attributes of 1 MiB each: each within its limit, together past the scene's 256 MiB.
  std::string many;
  for (int i = 0; i < 300; ++i)
    many += "  <bsdf type=\"diffuse\" id=\"b" + std::to_string(i) +
            "\"><rgb name=\"reflectance\" value=\"$x\"/></bsdf>\n";
  ExpectError(Load("  <default name=\"x\" value=\"" + big + "\"/>\n" + many),
              "scene.xml:", "expands past the limit");
  // Below both: 200 of them load.
  many.clear();
  for (int i = 0; i < 200; ++i)
    many += "  <bsdf type=\"diffuse\" id=\"b" + std::to_string(i) +
            "\"><rgb name=\"reflectance\" value=\"$x\"/></bsdf>\n";
  const absl::StatusOr<SceneDesc> ok =
      Load("  <default name=\"x\" value=\"" + big + "\"/>\n" + many);
  EXPECT_TRUE(ok.ok()) << ok.status().message().substr(0, 300);
}

// A crop window is checked in 64 bits: an offset of 2^31 - 1 wrapped the sum negative and passed.
TEST(SceneLoaderErrorTest, ACropWindowPastTheFilmIsRefused) {
  const auto scene = [](int offset) {
    return "<scene version=\"3.0.0\">\n<sensor type=\"perspective\">\n"
           "  <film type=\"hdrfilm\"><integer name=\"width\" value=\"64\"/>"
           "<integer name=\"height\" value=\"32\"/>"
           "<integer name=\"crop_offset_x\" value=\"" +
           std::to_string(offset) +
           "\"/><integer name=\"crop_width\" value=\"16\"/></film>\n</sensor>\n</scene>\n";
  };
  EXPECT_TRUE(LoadSceneString(scene(48), "scene.xml", {}).ok());
  ExpectError(LoadSceneString(scene(49), "scene.xml", {}), "scene.xml:", "is not inside the");
  ExpectError(LoadSceneString(scene(2147483647), "scene.xml", {}),
              "scene.xml:", "is not inside the");
}

TEST(SceneLoaderErrorTest, UnknownAndDuplicateIds) {
  ExpectError(Load("  <shape type=\"cube\">\n    <ref id=\"nope\"/>\n  </shape>\n"),
              "scene.xml:3:", "unknown id 'nope'");
  const auto r = Load(
      "  <bsdf type=\"diffuse\" id=\"white\"/>\n"
      "  <bsdf type=\"conductor\" id=\"white\"/>\n");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message(), "scene.xml:3: duplicate id 'white' (first defined at line 2)");
  ExpectError(Load("  <shape type=\"cube\" id=\"a\"/>\n  <shape type=\"cube\">\n"
                   "    <ref id=\"a\"/>\n  </shape>\n"),
              "scene.xml:4:", "id 'a' names a shape");
}

// Mitsuba 3 resolves <ref>s after reading the whole scene: a bsdf, texture or shapegroup may be
// defined after its first use (mitsuba 3.9.1 loads each of these; checked in Python).
TEST(SceneLoaderTest, ReferencesToIdsDefinedLater) {
  const auto scene = Load(R"(  <shape type="cube"><ref id="red"/></shape>
  <shape type="instance"><ref id="g"/></shape>
  <bsdf type="diffuse" id="red"><ref name="reflectance" id="wood"/></bsdf>
  <texture type="checkerboard" id="wood"><rgb name="color0" value="0.9, 0.1, 0.1"/></texture>
  <shape type="shapegroup" id="g"><shape type="sphere"><ref id="red"/></shape></shape>
  <bsdf type="diffuse" id="blue"><rgb name="reflectance" value="0.1, 0.1, 0.9"/></bsdf>
  <shape type="rectangle"><ref id="blue"/></shape>
)");
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->shapes.size(), 3u);
  ASSERT_EQ(scene->bsdfs.size(), 2u);  // each parsed once, where it was first needed
  ASSERT_EQ(scene->textures.size(), 1u);
  const BsdfDesc& red = scene->bsdfs.at(size_t(scene->shapes[0].bsdf));
  EXPECT_EQ(red.id, "red");
  EXPECT_EQ(red.Color("reflectance", Vec3(0)).texture, 0);
  ExpectNear(scene->textures[0].color0, Vec3(0.9f, 0.1f, 0.1f));
  EXPECT_EQ(scene->shapes[1].bsdf, scene->shapes[0].bsdf);  // the instanced sphere
  EXPECT_EQ(scene->bsdfs.at(size_t(scene->shapes[2].bsdf)).id, "blue");

  ExpectError(Load("  <shape type=\"cube\"><ref id=\"a\"/></shape>\n"
                   "  <bsdf type=\"twosided\" id=\"a\"><ref id=\"b\"/></bsdf>\n"
                   "  <bsdf type=\"twosided\" id=\"b\">\n    <ref id=\"a\"/></bsdf>\n"),
              "scene.xml:5:", "circular reference to id 'a'");
  // A long chain of later definitions is refused before it can exhaust the stack (each link
  // parses the next in place: nested parsing, bounded as nested objects and includes are).
  std::string chain = "  <shape type=\"cube\"><ref id=\"b0\"/></shape>\n";
  for (int i = 0; i < 200; ++i)
    chain += "  <bsdf type=\"twosided\" id=\"b" + std::to_string(i) + "\"><ref id=\"b" +
             std::to_string(i + 1) + "\"/></bsdf>\n";
  chain += "  <bsdf type=\"diffuse\" id=\"b200\"/>\n";
  ExpectError(Load(chain), "scene.xml:", "nested more than 128 deep");
  // Only top-level objects are found ahead; a shape's id still cannot be referenced.
  ExpectError(Load("  <shape type=\"cube\">\n    <ref id=\"s\"/></shape>\n"
                   "  <shape type=\"sphere\" id=\"s\"/>\n"),
              "scene.xml:3:", "unknown id 's'");
}

// <include filename="..."/>: an included <scene>'s children are read in its place (its
// <default>s set what is not set yet), an included object is one child named by the include.
// An include is found next to the file that names it (then next to the files that include that
// one, then in the scene folder); a parameter's file in the scene folder only, as Mitsuba's
// resolver has it when the plugins are made. Values as mitsuba 3.9.1 loads the same files; it
// refuses `tri.obj` named in sub/part.xml for sub/tri.obj ("file not found"), as here.
TEST(SceneLoaderTest, Includes) {
  const std::string dir = MakeDir("includes");
  fs::create_directories(dir + "/sub");
  WriteFile(dir + "/sub/mat.xml",
            "<bsdf type=\"diffuse\" version=\"3.0.0\">\n"
            "  <rgb name=\"reflectance\" value=\"0.2, 0.3, 0.4\"/></bsdf>\n");
  WriteFile(dir + "/sub/part.xml", R"(<scene version="3.0.0">
  <default name="r" value="0.7"/>
  <default name="s" value="0.1"/>
  <bsdf type="diffuse" id="late"><rgb name="reflectance" value="$r, $s, $s"/></bsdf>
  <shape type="obj"><string name="filename" value="sub/tri.obj"/><ref id="late"/></shape>
  <shape type="disk"><include filename="mat.xml"/></shape>
</scene>
)");
  WriteFile(dir + "/sub/tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  WriteFile(dir + "/scene.xml", Wrap(R"(  <default name="s" value="0.5"/>
  <shape type="sphere"><ref id="late"/></shape>
  <shape type="rectangle"><include filename="sub/mat.xml"/></shape>
  <include filename="sub/part.xml"/>
  <shape type="cube"><ref id="late"/></shape>
)"));
  const auto scene = LoadSceneFile(dir + "/scene.xml", {});
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->shapes.size(), 5u);
  const BsdfDesc& late = scene->bsdfs.at(size_t(scene->shapes[0].bsdf));  // a <ref> before it
  ExpectNear(late.Color("reflectance", Vec3(0)).value, Vec3(0.7f, 0.5f, 0.5f));  // s: the scene's
  EXPECT_EQ(late.loc.file, dir + "/sub/part.xml");
  EXPECT_EQ(late.loc.line, 4);
  ExpectNear(scene->bsdfs.at(size_t(scene->shapes[1].bsdf)).Color("reflectance", Vec3(0)).value,
             Vec3(0.2f, 0.3f, 0.4f));
  EXPECT_EQ(scene->shapes[2].mesh.positions.size(), 3u);
  EXPECT_EQ(scene->shapes[2].bsdf, scene->shapes[0].bsdf);
  // sub/part.xml's "mat.xml" is sub/mat.xml, next to it.
  ExpectNear(scene->bsdfs.at(size_t(scene->shapes[3].bsdf)).Color("reflectance", Vec3(0)).value,
             Vec3(0.2f, 0.3f, 0.4f));
  EXPECT_EQ(scene->shapes[4].bsdf, scene->shapes[0].bsdf);

  // Errors name the file and line they are in.
  WriteFile(dir + "/sub/near.xml",
            "<scene version=\"3.0.0\">\n  <shape type=\"obj\">"
            "<string name=\"filename\" value=\"tri.obj\"/></shape>\n"
            "</scene>\n");
  WriteFile(dir + "/near.xml", Wrap("  <include filename=\"sub/near.xml\"/>\n"));
  ExpectError(LoadSceneFile(dir + "/near.xml", {}), dir + "/sub/near.xml:2:", "not found",
              absl::StatusCode::kNotFound);
  WriteFile(dir + "/sub/bad.xml",
            "<scene version=\"3.0.0\">\n  <shape type=\"torus\"/>\n</scene>\n");
  WriteFile(dir + "/bad.xml", Wrap("  <include filename=\"sub/bad.xml\"/>\n"));
  ExpectError(LoadSceneFile(dir + "/bad.xml", {}), dir + "/sub/bad.xml:2:", "unknown shape type");
  WriteFile(dir + "/sub/broken.xml", "<scene version=\"3.0.0\">\n  <shape type=\"cube\">\n");
  WriteFile(dir + "/broken.xml", Wrap("  <include filename=\"sub/broken.xml\"/>\n"));
  ExpectError(LoadSceneFile(dir + "/broken.xml", {}), dir + "/sub/broken.xml:", "malformed XML");
  WriteFile(dir + "/missing.xml", Wrap("  <include filename=\"sub/none.xml\"/>\n"));
  ExpectError(LoadSceneFile(dir + "/missing.xml", {}), dir + "/missing.xml:2:", "not found",
              absl::StatusCode::kNotFound);
  WriteFile(dir + "/outside.xml", Wrap("  <include filename=\"../x.xml\"/>\n"));
  ExpectError(LoadSceneFile(dir + "/outside.xml", {}),
              dir + "/outside.xml:2:", "leaves the scene folder");
  WriteFile(dir + "/sub/loop.xml",
            "<scene version=\"3.0.0\">\n  <include filename=\"loop.xml\"/>\n"
            "</scene>\n");
  WriteFile(dir + "/loop.xml", Wrap("  <include filename=\"sub/loop.xml\"/>\n"));
  ExpectError(LoadSceneFile(dir + "/loop.xml", {}), dir + "/sub/loop.xml:2:", "nested 15 deep");
  WriteFile(dir + "/sub/film.xml", "<integer name=\"width\" value=\"3\"/>\n");
  WriteFile(dir + "/notobject.xml", Wrap("  <include filename=\"sub/film.xml\"/>\n"));
  ExpectError(LoadSceneFile(dir + "/notobject.xml", {}),
              dir + "/sub/film.xml:1:", "holds a <scene> or one object");
  // A second sensor in an included file names where the first one is.
  WriteFile(dir + "/sub/sensor.xml",
            std::string("<scene version=\"3.0.0\">\n") + kSensor + "</scene>\n");
  WriteFile(dir + "/sensors.xml", Wrap("  <include filename=\"sub/sensor.xml\"/>\n"));
  ExpectError(LoadSceneFile(dir + "/sensors.xml", {}),
              dir + "/sensors.xml:3:", "(the first is at " + dir + "/sub/sensor.xml:2)");
  // An included emitter in a shapegroup's shape is refused as a written one is.
  WriteFile(dir + "/sub/lamp.xml", "<emitter type=\"area\" version=\"3.0.0\"/>\n");
  WriteFile(dir + "/group.xml",
            Wrap("  <shape type=\"shapegroup\" id=\"g\"><shape type=\"sphere\">\n"
                 "    <include filename=\"sub/lamp.xml\"/></shape></shape>\n"));
  ExpectError(LoadSceneFile(dir + "/group.xml", {}),
              dir + "/sub/lamp.xml:1:", "a shape in a shapegroup cannot emit");
}

// What an uploaded scene can make the loader do is bounded across includes: nesting restarts in
// each included file, so 14 files of 20 nested masks each (280 levels) are refused by the one
// count of nested parsing (they recursed 280 deep before; a longer chain of includes and
// references exhausted the stack); and included files are sized before they are read (a 300 MB
// file, sparse here, is refused without reading it).
TEST(SceneLoaderErrorTest, IncludesCannotExhaustTheLoader) {
  const std::string dir = MakeDir("include_limits");
  for (int k = 1; k <= 14; ++k) {
    std::string open, close;
    for (int i = 0; i < 20; ++i) {
      open += i == 0 ? "<bsdf type=\"mask\" version=\"3.0.0\">" : "<bsdf type=\"mask\">";
      close += "</bsdf>";
    }
    const std::string inner = k < 14 ? "<include filename=\"" + std::to_string(k + 1) + ".xml\"/>"
                                     : "<bsdf type=\"diffuse\"/>";
    WriteFile(dir + "/" + std::to_string(k) + ".xml", open + inner + close + "\n");
  }
  WriteFile(dir + "/deep.xml",
            Wrap("  <shape type=\"cube\"><include filename=\"1.xml\"/></shape>\n"));
  ExpectError(LoadSceneFile(dir + "/deep.xml", {}), dir + "/", "nested more than 128 deep");

  const std::string big = dir + "/big.xml";
  WriteFile(big, "");
  fs::resize_file(big, uintmax_t{300} << 20);
  WriteFile(dir + "/huge.xml", Wrap("  <include filename=\"big.xml\"/>\n"));
  ExpectError(LoadSceneFile(dir + "/huge.xml", {}),
              dir + "/huge.xml:2:", "more than 256 MB in all");
  fs::remove(big);
}

TEST(SceneLoaderErrorTest, UnsupportedFeatures) {
  const std::string unknown = std::string(R"(<scene version="3.0.0">
  <sensor type="perspective">
    <film type="hdrfilm">
      <rfilter type="sinc"/>
    </film>
  </sensor>
</scene>
)");
  ExpectError(LoadSceneString(unknown, "s.xml", {}), "s.xml:4:",
              "unknown rfilter type 'sinc' (supported: box, gaussian, tent, mitchell, catmullrom, "
              "lanczos)");
  ExpectError(Load("  <bsdf type=\"conductor\">\n    <string name=\"material\" value=\"Xx\"/>\n"
                   "  </bsdf>\n"),
              "scene.xml:3:", "unknown conductor material 'Xx' (supported: none, a-C, Ag,");
  ExpectError(Load("  <emitter type=\"area\"/>\n"), "scene.xml:2:", "must be nested in a <shape>");
  ExpectError(LoadSceneString("<scene version=\"3.0.0\">\n</scene>\n", "s.xml", {}),
              "s.xml:1:", "no <sensor>");
}

// The film's reconstruction filter: Mitsuba 3's plugins, parameters and defaults (gaussian
// stddev 0.5 cut at 4 stddev, tent radius 1, gaussian when the film or the filter is missing).
// Filters with negative lobes load as the gaussian nearest their kernel, with a warning at their
// line; their parameters are still checked.
TEST(SceneLoaderTest, NegativeLobedFiltersBecomeTheNearestGaussian) {
  for (const char* filter :
       {R"(<rfilter type="mitchell"><float name="B" value="0.3"/></rfilter>)",
        R"(<rfilter type="catmullrom"/>)",
        R"(<rfilter type="lanczos"><integer name="lobes" value="2"/></rfilter>)"}) {
    const std::string xml = std::string(
                                "<scene version=\"3.0.0\">\n<sensor type=\"perspective\">\n"
                                "<film type=\"hdrfilm\">\n") +
                            filter + "\n</film>\n</sensor>\n</scene>\n";
    absl::StatusOr<SceneDesc> d = LoadSceneString(xml, "s.xml", {});
    ASSERT_TRUE(d.ok()) << filter << ": " << d.status();
    EXPECT_EQ(d->camera.filter.type, FilterType::kGaussian);
    // The gaussian nearest the kernel (see scene_loader.cc): 0.45 for mitchell, 0.40 otherwise.
    const float stddev = std::string(filter).find("mitchell") != std::string::npos ? 0.45f : 0.40f;
    EXPECT_FLOAT_EQ(d->camera.filter.stddev, stddev);
    EXPECT_FLOAT_EQ(d->camera.filter.radius, 4 * stddev);
    ASSERT_EQ(d->warnings.size(), 1u) << filter;
    EXPECT_NE(d->warnings[0].find("s.xml:4:"), std::string::npos) << d->warnings[0];
    EXPECT_NE(d->warnings[0].find("gaussian"), std::string::npos) << d->warnings[0];
  }
  const std::string bad =
      "<scene version=\"3.0.0\">\n<sensor type=\"perspective\">\n<film type=\"hdrfilm\">\n"
      "<rfilter type=\"mitchell\"><float name=\"B\" value=\"x\"/></rfilter>\n</film>\n</sensor>\n"
      "</scene>\n";
  EXPECT_FALSE(LoadSceneString(bad, "s.xml", {}).ok());
}

TEST(SceneLoaderTest, ReconstructionFilters) {
  auto film = [](const std::string& filter) {
    return "<scene version=\"3.0.0\">\n  <sensor type=\"perspective\">\n"
           "    <film type=\"hdrfilm\">\n" +
           filter + "    </film>\n  </sensor>\n</scene>\n";
  };
  auto filter_of = [](const absl::StatusOr<SceneDesc>& s) {
    EXPECT_TRUE(s.ok()) << s.status();
    EXPECT_TRUE(!s.ok() || s->warnings.empty()) << s->warnings[0];
    return s.ok() ? s->camera.filter : FilterDesc{};
  };
  FilterDesc f = filter_of(LoadSceneString(film(""), "s.xml", {}));
  EXPECT_EQ(f.type, FilterType::kGaussian);
  EXPECT_FLOAT_EQ(f.stddev, 0.5f);
  EXPECT_FLOAT_EQ(f.radius, 2);
  f = filter_of(LoadSceneString(film("      <rfilter type=\"gaussian\"/>\n"), "s.xml", {}));
  EXPECT_EQ(f.type, FilterType::kGaussian);
  EXPECT_FLOAT_EQ(f.radius, 2);
  f = filter_of(
      LoadSceneString(film("      <rfilter type=\"gaussian\"><float name=\"stddev\" value=\"0.3\"/>"
                           "</rfilter>\n"),
                      "s.xml", {}));
  EXPECT_FLOAT_EQ(f.stddev, 0.3f);
  EXPECT_FLOAT_EQ(f.radius, 1.2f);
  f = filter_of(LoadSceneString(film("      <rfilter type=\"tent\"/>\n"), "s.xml", {}));
  EXPECT_EQ(f.type, FilterType::kTent);
  EXPECT_FLOAT_EQ(f.radius, 1);
  f = filter_of(LoadSceneString(
      film("      <rfilter type=\"tent\"><float name=\"radius\" value=\"1.5\"/></rfilter>\n"),
      "s.xml", {}));
  EXPECT_FLOAT_EQ(f.radius, 1.5f);
  f = filter_of(LoadSceneString(film("      <rfilter type=\"box\"/>\n"), "s.xml", {}));
  EXPECT_EQ(f.type, FilterType::kBox);
  EXPECT_FLOAT_EQ(f.radius, 0.5f);
  // No film at all: Mitsuba's default film, with its gaussian filter (and a warning).
  const auto no_film = LoadSceneString(
      "<scene version=\"3.0.0\">\n  <sensor type=\"perspective\"/>\n</scene>\n", "s.xml", {});
  ASSERT_TRUE(no_film.ok()) << no_film.status();
  EXPECT_EQ(no_film->camera.filter.type, FilterType::kGaussian);

  ExpectError(LoadSceneString(film("      <rfilter type=\"gaussian\">\n        <float "
                                   "name=\"stddev\" value=\"0\"/>\n      </rfilter>\n"),
                              "s.xml", {}),
              "s.xml:5:", "stddev must be positive");
  ExpectError(LoadSceneString(film("      <rfilter type=\"tent\">\n        <float "
                                   "name=\"radius\" value=\"-1\"/>\n      </rfilter>\n"),
                              "s.xml", {}),
              "s.xml:5:", "radius must be positive");
  ExpectError(LoadSceneString(film("      <rfilter type=\"box\">\n        <float "
                                   "name=\"radius\" value=\"1\"/>\n      </rfilter>\n"),
                              "s.xml", {}),
              "s.xml:5:", "radius");
}

// ---------------------------------------------------------------- transforms and camera

TEST(SceneLoaderTest, TransformsApplyInDocumentOrder) {
  ExpectNear(SphereCenterAfter("<translate x=\"1\"/><scale value=\"2\"/>"), Vec3(2, 0, 0));
  ExpectNear(SphereCenterAfter("<scale value=\"2\"/><translate x=\"1\"/>"), Vec3(1, 0, 0));
  ExpectNear(SphereCenterAfter("<translate value=\"1, 0, 0\"/><rotate z=\"1\" angle=\"90\"/>"),
             Vec3(0, 1, 0));
  ExpectNear(SphereCenterAfter("<translate x=\"1\"/><rotate axis=\"0, 0, 1\" angle=\"90\"/>"
                               "<translate y=\"2\"/>"),
             Vec3(0, 3, 0));
  ExpectNear(SphereCenterAfter("<translate x=\"1\" y=\"1\" z=\"1\"/><scale value=\"1 2 3\"/>"),
             Vec3(1, 2, 3));
  ExpectNear(SphereCenterAfter("<matrix value=\"1 0 0 5  0 1 0 6  0 0 1 7  0 0 0 1\"/>"),
             Vec3(5, 6, 7));
}

TEST(SceneLoaderTest, SphereRadiusScalesWithItsToWorld) {
  // Uniform scale (with a rotation): the radius grows by it, no warning.
  auto scene = Load(R"(  <shape type="sphere">
    <float name="radius" value="0.5"/>
    <transform name="to_world"><scale value="3"/><rotate x="1" angle="30"/></transform>
  </shape>
)");
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_NEAR(scene->shapes.at(0).radius, 1.5f, 1e-5f);
  EXPECT_TRUE(scene->warnings.empty());
  // Uneven scale: kept round, with the x scale as Mitsuba 3 takes it (not cbrt |det|, which
  // would be 0.5 * 2^(1/3) for x = 2 alone), and a warning at the to_world's line.
  for (const char* scale : {R"(x="2" y="4" z="1")", R"(x="2")"}) {
    scene = Load(std::string(R"(  <shape type="sphere">
    <point name="center" value="1, 0, 0"/>
    <float name="radius" value="0.5"/>
    <transform name="to_world"><scale )") +
                 scale + R"(/><translate z="3"/></transform>
  </shape>
)");
    ASSERT_TRUE(scene.ok()) << scene.status();
    const ShapeDesc& s = scene->shapes.at(0);
    EXPECT_EQ(s.type, ShapeType::kSphere);
    ExpectNear(s.center, Vec3(2, 0, 3));
    EXPECT_NEAR(s.radius, 0.5f * 2, 1e-5f) << scale;
    ASSERT_EQ(scene->warnings.size(), 1u) << scale;
    EXPECT_NE(scene->warnings[0].find("unevenly"), std::string::npos) << scene->warnings[0];
  }
}

// <lookat> without up (or with a zero one): Mitsuba 3.9.1 takes the first vector of
// coordinate_system(dir); the camera frames below are its own (sensor.world_transform()). The
// second vector was taken, which rolled the image 90 degrees.
TEST(SceneLoaderTest, LookAtWithoutUpIsMitsubasFrame) {
  struct Case {
    const char* attributes;
    Vec3 x, y, z;
  };
  const Case cases[] = {
      {R"(origin="0,0,0" target="1,0,0")", Vec3(0, -1, 0), Vec3(0, 0, -1), Vec3(1, 0, 0)},
      {R"(origin="1,2,3" target="0.5,-1,2")", Vec3(-0.111511f, 0.330933f, -0.937043f),
       Vec3(0.981415f, -0.111511f, -0.156174f), Vec3(-0.156174f, -0.937043f, -0.312348f)},
      {R"(origin="0,0,5" target="0,0,0" up="0,0,0")", Vec3(0, 1, 0), Vec3(1, 0, 0),
       Vec3(0, 0, -1)}};
  for (const Case& c : cases) {
    const auto scene = LoadSceneString(std::string(R"(<scene version="3.0.0">
  <sensor type="perspective"><transform name="to_world"><lookat )") +
                                           c.attributes + R"(/></transform></sensor>
</scene>
)",
                                       "s.xml", {});
    ASSERT_TRUE(scene.ok()) << scene.status();
    ExpectNear(Column(scene->camera.to_world, 0), c.x);
    ExpectNear(Column(scene->camera.to_world, 1), c.y);
    ExpectNear(Column(scene->camera.to_world, 2), c.z);
  }
}

// perspective's principal_point_offset_x / _y (Mitsuba's Blender exporter writes them) move the
// image centre; the ray directions are Mitsuba 3.9.1's own (sensor.sample_ray at film positions
// (0.5, 0.5) and (0.25, 0.75) of a 64 x 48 film, fov 40, offsets 0.1 and -0.05). A camera
// to_world with a scale is refused, as Mitsuba refuses it; a mirror is not a scale.
TEST(SceneLoaderTest, PrincipalPointOffsetAndCameraScale) {
  const auto scene = LoadSceneString(R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="40"/>
    <float name="principal_point_offset_x" value="0.1"/>
    <float name="principal_point_offset_y" value="-0.05"/>
    <transform name="to_world"><lookat origin="0,0,0" target="0,0,1" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="48"/>
    </film></sensor>
</scene>
)",
                                     "s.xml", {});
  ASSERT_TRUE(scene.ok()) << scene.status();
  const Camera cam(scene->camera);
  ExpectNear(cam.Direction(32, 24), Vec3(-0.072575f, 0.027216f, 0.996992f));
  ExpectNear(cam.Direction(16, 36), Vec3(0.107912f, -0.107912f, 0.988286f));
  const auto with = [](const std::string& transform) {
    return LoadSceneString(R"(<scene version="3.0.0"><sensor type="perspective">
  <transform name="to_world">)" +
                               transform + R"(</transform></sensor></scene>
)",
                           "s.xml", {});
  };
  ExpectError(with(R"(<scale value="2"/>)"), "s.xml:2:", "scale factors in the camera's to_world");
  EXPECT_TRUE(with(R"(<scale x="-1"/><rotate y="1" angle="30"/>)").ok());
}

TEST(SceneLoaderTest, LookAtBuildsMitsubaCameraFrame) {
  const auto scene = LoadSceneString(R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="39.3077"/>
    <float name="near_clip" value="0.5"/>
    <float name="far_clip" value="50"/>
    <transform name="to_world">
      <lookat origin="0, 0, 3.9" target="0, 0, 0" up="0, 1, 0"/>
    </transform>
  </sensor>
</scene>
)",
                                     "s.xml", {});
  ASSERT_TRUE(scene.ok()) << scene.status();
  const CameraDesc& cam = scene->camera;
  ExpectNear(Column(cam.to_world, 0), Vec3(-1, 0, 0));  // +x is the image's left
  ExpectNear(Column(cam.to_world, 1), Vec3(0, 1, 0));
  ExpectNear(Column(cam.to_world, 2), Vec3(0, 0, -1));  // looks along +z
  ExpectNear(Column(cam.to_world, 3), Vec3(0, 0, 3.9f));
  EXPECT_FLOAT_EQ(cam.fov_x_deg, 39.3077f);
  EXPECT_FLOAT_EQ(cam.near_clip, 0.5f);
  EXPECT_FLOAT_EQ(cam.far_clip, 50);
  EXPECT_EQ(cam.loc.line, 2);
  // No film: Mitsuba's default size; the scene is still accepted, with a warning.
  EXPECT_EQ(cam.width, 768);
  EXPECT_EQ(cam.height, 576);
  EXPECT_EQ(scene->warnings.size(), 1u);
}

float FovXFor(const std::string& axis, float fov, int width, int height,
              const std::string& crop = "") {
  const std::string xml =
      "<scene version=\"3.0.0\"><sensor type=\"perspective\">"
      "<float name=\"fov\" value=\"" +
      std::to_string(fov) +
      "\"/>"
      "<string name=\"fov_axis\" value=\"" +
      axis +
      "\"/>"
      "<film type=\"hdrfilm\"><integer name=\"width\" value=\"" +
      std::to_string(width) + "\"/><integer name=\"height\" value=\"" + std::to_string(height) +
      "\"/>" + crop +
      "<rfilter type=\"box\"/></film>"
      "</sensor></scene>";
  const auto scene = LoadSceneString(xml, "s.xml", {});
  EXPECT_TRUE(scene.ok()) << scene.status();
  return scene.ok() ? scene->camera.fov_x_deg : NAN;
}

TEST(SceneLoaderTest, FovAxisConvertsToHorizontal) {
  const auto deg = [](double r) { return float(r * 180 / 3.14159265358979323846); };
  const double t = std::tan(45.0 / 2 * 3.14159265358979323846 / 180);
  EXPECT_FLOAT_EQ(FovXFor("x", 45, 200, 100), 45);
  EXPECT_NEAR(FovXFor("y", 45, 200, 100), deg(2 * std::atan(t * 2)), 1e-4);
  // Diagonal: the half-diagonal tangent t splits as w : h on the film.
  EXPECT_NEAR(FovXFor("diagonal", 45, 300, 400), deg(2 * std::atan(t * 3 / 5)), 1e-4);
  EXPECT_NEAR(FovXFor("smaller", 45, 200, 100), deg(2 * std::atan(t * 2)), 1e-4);  // y is smaller
  EXPECT_FLOAT_EQ(FovXFor("smaller", 45, 100, 200), 45);
  EXPECT_FLOAT_EQ(FovXFor("larger", 45, 200, 100), 45);
  EXPECT_NEAR(FovXFor("larger", 45, 100, 200), deg(2 * std::atan(t / 2)), 1e-4);  // y is larger
  // A crop window takes the whole film's fov (Mitsuba's parse_fov uses the film's size): a 16 x 32
  // crop of a 64 x 32 film with fov_axis y is rendered at the full film's zoom, 98.2 degrees
  // across the film, not 2 atan(tan 22.5 / 2) across the crop's own aspect.
  const std::string crop = "<integer name=\"crop_width\" value=\"16\"/>";
  EXPECT_NEAR(FovXFor("y", 60, 64, 32, crop), FovXFor("y", 60, 64, 32), 1e-5);
  EXPECT_NEAR(FovXFor("y", 60, 64, 32, crop),
              deg(2 * std::atan(std::tan(3.14159265358979 / 6) * 2)), 1e-4);
  EXPECT_NEAR(FovXFor("diagonal", 45, 300, 400, "<integer name=\"crop_height\" value=\"100\"/>"),
              deg(2 * std::atan(t * 3 / 5)), 1e-4);
  ExpectError(LoadSceneString("<scene version=\"3.0.0\"><sensor type=\"perspective\">\n"
                              "<string name=\"fov_axis\" value=\"z\"/></sensor></scene>",
                              "s.xml", {}),
              "s.xml:2:", "unknown fov_axis 'z'");
}

TEST(SceneLoaderTest, CameraFromMatrix) {
  const auto scene = LoadSceneString(R"(<scene version="3.0.0">
  <sensor type="perspective">
    <transform name="to_world">
      <matrix value="-1 0 0 1  0 1 0 2  0 0 -1 3  0 0 0 1"/>
    </transform>
  </sensor>
</scene>
)",
                                     "s.xml", {});
  ASSERT_TRUE(scene.ok()) << scene.status();
  ExpectNear(Column(scene->camera.to_world, 2), Vec3(0, 0, -1));
  ExpectNear(Column(scene->camera.to_world, 3), Vec3(1, 2, 3));
  // Without fov: Mitsuba's 50 mm lens on 36 x 24 mm, diagonal, on the 768 x 576 default film.
  EXPECT_NEAR(scene->camera.fov_x_deg, 38.1848f, 1e-3f);
}

// Parameters Mitsuba 3's perspective camera reads: focal_length (35 mm equivalent, in place of
// fov; x_fov 52.6225 for "35mm" on 320 x 240, Mitsuba 3.9.1's own x_fov), focus_distance and the
// shutter (no effect on a pinhole image of a still scene). Bitterli's interiors set
// focusDistance.
TEST(SceneLoaderTest, PerspectiveFocalLengthFocusAndShutter) {
  const auto load = [](const std::string& params) {
    return LoadSceneString("<scene version=\"3.0.0\"><sensor type=\"perspective\">\n" + params +
                               "<film type=\"hdrfilm\"><integer name=\"width\" value=\"320\"/>"
                               "<integer name=\"height\" value=\"240\"/></film></sensor></scene>",
                           "s.xml", {});
  };
  const auto scene = load(
      "<string name=\"focal_length\" value=\"35mm\"/><float name=\"focus_distance\" "
      "value=\"3\"/><float name=\"shutter_open\" value=\"0\"/><float name=\"shutter_close\" "
      "value=\"0.5\"/>");
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_NEAR(scene->camera.fov_x_deg, 52.6225f, 1e-3f);
  ExpectError(load("<string name=\"focal_length\" value=\"wide\"/>"),
              "s.xml:2:", "focal_length must be a positive length");
  ExpectError(load("<float name=\"fov\" value=\"40\"/>\n<string name=\"focal_length\" "
                   "value=\"35mm\"/>"),
              "s.xml:3:", "either fov or focal_length");
  ExpectError(load("<float name=\"focus_distance\" value=\"-1\"/>"),
              "s.xml:2:", "focus_distance must be finite and not negative");
}

// ---------------------------------------------------------------- $defaults and -D defines

constexpr char kParameterized[] = R"(<scene version="3.0.0">
  <default name="spp" value="8"/>
  <default name="resx" value="32"/>
  <integrator type="path">
    <integer name="max_depth" value="$depth"/>
  </integrator>
  <sensor type="perspective">
    <float name="fov" value="$fov"/>
    <sampler type="independent">
      <integer name="sample_count" value="$spp"/>
    </sampler>
    <film type="hdrfilm">
      <integer name="width" value="$resx"/>
      <integer name="height" value="2$resx"/>
      <rfilter type="box"/>
    </film>
  </sensor>
</scene>
)";

TEST(SceneLoaderTest, DefaultsAndDefines) {
  LoadOptions options;
  options.defines = {{"depth", "3"}, {"fov", "30"}};  // no <default> for these two
  auto scene = LoadSceneString(kParameterized, "p.xml", options);
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(scene->camera.spp, 8);
  EXPECT_EQ(scene->camera.width, 32);
  EXPECT_EQ(scene->camera.height, 232);  // "2$resx": substitution inside a value
  EXPECT_EQ(scene->integrator.max_depth, 3);
  EXPECT_FLOAT_EQ(scene->camera.fov_x_deg, 30);

  options.defines["spp"] = "16";  // -D spp=16 overrides the default
  scene = LoadSceneString(kParameterized, "p.xml", options);
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(scene->camera.spp, 16);

  options.defines.erase("fov");
  ExpectError(LoadSceneString(kParameterized, "p.xml", options),
              "p.xml:8:", "undefined parameter '$fov'");
}

// A Mitsuba 0.5 file as Bitterli's downloads are written: camelCase names, hdrfilm's output
// parameters, a tent filter, strictNormals; upgraded on load as Mitsuba 3 does.
TEST(SceneLoaderTest, UpgradesMitsuba05Syntax) {
  const auto scene = LoadSceneString(R"(<scene version="0.5.0">
  <integrator type="path">
    <integer name="maxDepth" value="65"/>
    <boolean name="strictNormals" value="true"/>
  </integrator>
  <sensor type="perspective">
    <float name="farClip" value="2800"/>
    <float name="fov" value="90"/>
    <string name="fovAxis" value="x"/>
    <float name="nearClip" value="0.1"/>
    <transform name="toWorld">
      <lookAt origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>
    </transform>
    <sampler type="sobol">
      <integer name="sampleCount" value="64"/>
    </sampler>
    <film type="hdrfilm">
      <integer name="width" value="64"/>
      <integer name="height" value="32"/>
      <integer name="cropOffsetX" value="8"/>
      <integer name="cropWidth" value="16"/>
      <string name="fileFormat" value="openexr"/>
      <string name="pixelFormat" value="rgb"/>
      <boolean name="banner" value="false"/>
      <boolean name="highQualityEdges" value="false"/>
      <rfilter type="tent"/>
    </film>
  </sensor>
  <bsdf type="roughplastic" id="floor">
    <float name="intIOR" value="1.5"/>
    <float name="extIOR" value="1"/>
    <string name="distribution" value="ggx"/>
    <rgb name="diffuseReflectance" value="0.5, 0.4, 0.3"/>
    <boolean name="nonlinear" value="true"/>
  </bsdf>
  <shape type="rectangle">
    <ref id="floor"/>
  </shape>
</scene>
)",
                                     "old.xml", {});
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(scene->integrator.max_depth, 65);
  EXPECT_EQ(scene->camera.spp, 64);
  EXPECT_FLOAT_EQ(scene->camera.near_clip, 0.1f);
  EXPECT_EQ(scene->camera.film_width, 64);
  EXPECT_EQ(scene->camera.width, 16);
  EXPECT_EQ(scene->camera.height, 32);
  EXPECT_EQ(scene->camera.crop_x, 8);
  ASSERT_EQ(scene->bsdfs.size(), 1u);
  EXPECT_EQ(scene->bsdfs[0].type, "roughplastic");
  EXPECT_FLOAT_EQ(scene->bsdfs[0].Float("int_ior", 0), 1.5f);
  ExpectNear(scene->bsdfs[0].Color("diffuse_reflectance", Vec3()).value, Vec3(0.5f, 0.4f, 0.3f));
  EXPECT_EQ(scene->camera.filter.type, FilterType::kTent);
  EXPECT_FLOAT_EQ(scene->camera.filter.radius, 1);  // Mitsuba's default
  for (const std::string& w : scene->warnings) EXPECT_EQ(w.find("rfilter"), std::string::npos) << w;
  // The same names in a version 3 file are unknown parameters.
  ExpectError(LoadSceneString("<scene version=\"3.0.0\">\n  <bsdf type=\"plastic\">\n"
                              "    <float name=\"intIOR\" value=\"1.5\"/>\n  </bsdf>\n</scene>\n",
                              "new.xml", {}),
              "new.xml:3:", "unknown parameter 'intIOR'");
}

// Mitsuba 3's two other upgrades of a 0.5 file: a diffuse BSDF's diffuseReflectance is its
// reflectance, and a texture's uoffset / voffset / uscale / vscale become to_uv (translate, then
// scale: (u, v) -> (uscale (u + uoffset), vscale (v + voffset))), as in layered_kitchen of
// github.com/VElysianP/mitsuba_scenes, which failed on "unexpected <texture> in bsdf 'diffuse'".
TEST(SceneLoaderTest, UpgradesMitsuba05DiffuseAndUvScale) {
  const auto scene = LoadSceneString(R"(<scene version="0.5.0">
  <sensor type="perspective"/>
  <bsdf type="diffuse" id="tiles">
    <texture name="diffuseReflectance" type="checkerboard">
      <float name="uscale" value="2"/>
      <float name="vscale" value="3"/>
      <float name="uoffset" value="0.5"/>
      <float name="voffset" value="0.25"/>
    </texture>
  </bsdf>
  <bsdf type="diffuse" id="wall">
    <rgb name="diffuseReflectance" value="0.2, 0.3, 0.4"/>
  </bsdf>
  <bsdf type="plastic" id="varnish">
    <rgb name="diffuseReflectance" value="0.6, 0.5, 0.4"/>
  </bsdf>
</scene>
)",
                                     "old.xml", {});
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->bsdfs.size(), 3u);
  ASSERT_EQ(scene->bsdfs[0].colors.count("reflectance"), 1u);
  const int t = scene->bsdfs[0].colors.at("reflectance").texture;
  ASSERT_GE(t, 0);
  const std::array<float, 6> expected{2, 0, 1, 0, 3, 0.75f};
  for (int k = 0; k < 6; ++k)
    EXPECT_FLOAT_EQ(scene->textures[size_t(t)].to_uv[size_t(k)], expected[size_t(k)]) << k;
  ExpectNear(scene->bsdfs[1].Color("reflectance", Vec3()).value, Vec3(0.2f, 0.3f, 0.4f));
  // Only a diffuse BSDF's: plastic keeps its diffuse_reflectance.
  ExpectNear(scene->bsdfs[2].Color("diffuse_reflectance", Vec3()).value, Vec3(0.6f, 0.5f, 0.4f));
  // A bad number is reported where it is written, before it moves into the transform.
  ExpectError(
      LoadSceneString("<scene version=\"0.5.0\">\n  <texture type=\"checkerboard\" id=\"c\">\n"
                      "    <float name=\"uscale\" value=\"two\"/>\n  </texture>\n</scene>\n",
                      "bad.xml", {}),
      "bad.xml:3:", "uscale");
}

// Mitsuba 0.6's other global-illumination integrators in a 0.x file (flower_bedroom of
// github.com/VElysianP/mitsuba_scenes names bdpt) read as path, with a warning naming what was not
// read; in a 3.x file bdpt stays an error (SceneLoaderErrorTest.UnknownPluginType), as in
// Mitsuba 3.
TEST(SceneLoaderTest, Mitsuba06EstimatorsReadAsPath) {
  const auto scene = LoadSceneString(R"(<scene version="0.6.0">
  <integrator type="bdpt">
    <integer name="maxDepth" value="7"/>
    <boolean name="lightImage" value="true"/>
  </integrator>
  <sensor type="perspective"/>
</scene>
)",
                                     "old.xml", {});
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(scene->integrator.type, "path");
  EXPECT_EQ(scene->integrator.max_depth, 7);
  bool warned = false;
  for (const std::string& w : scene->warnings)
    warned |= w.rfind("old.xml:2:", 0) == 0 && w.find("'bdpt' read as path") != std::string::npos &&
              w.find("not read: light_image") != std::string::npos;
  EXPECT_TRUE(warned);
  // An estimator of another image is still an error in a 0.x file.
  ExpectError(LoadSceneString("<scene version=\"0.6.0\">\n  <integrator type=\"ao\"/>\n"
                              "  <sensor type=\"perspective\"/>\n</scene>\n",
                              "old.xml", {}),
              "old.xml:2:", "unknown integrator type 'ao'");
}

// The BSDFs beyond the subset: parameters recorded by name, named conductor materials, and
// Mitsuba's errors (file:line) for contradictory or unknown parameters.
TEST(SceneLoaderTest, GlossyMaterials) {
  const auto scene = Load(R"(  <bsdf type="roughconductor" id="gold">
    <string name="distribution" value="ggx"/>
    <float name="alpha_u" value="0.1"/>
    <float name="alpha_v" value="0.3"/>
    <string name="material" value="Au"/>
  </bsdf>
  <bsdf type="mask" id="leaf">
    <float name="opacity" value="0.25"/>
    <bsdf type="roughplastic">
      <float name="alpha" value="0.2"/>
    </bsdf>
  </bsdf>
  <bsdf type="roughdielectric" id="frost">
    <float name="alpha" value="0.3"/>
    <string name="int_ior" value="bk7"/>
  </bsdf>
)");
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->bsdfs.size(), 4u);  // gold, the mask's nested roughplastic, leaf, frost
  const BsdfDesc& gold = scene->bsdfs[0];
  EXPECT_EQ(gold.String("distribution", ""), "ggx");
  EXPECT_FLOAT_EQ(gold.Color("alpha_v", Vec3()).value.x, 0.3f);
  // Mitsuba 3.9.1's RGB eta of gold (scalar_rgb), see conductor_params.h.
  EXPECT_NEAR(gold.Color("eta", Vec3()).value.x, 0.143036f, 1e-5f);
  EXPECT_EQ(scene->bsdfs[1].type, "roughplastic");
  EXPECT_EQ(scene->bsdfs[1].String("distribution", ""), "beckmann");  // Mitsuba's default
  EXPECT_EQ(scene->bsdfs[2].nested, std::vector<int>{1});
  EXPECT_FLOAT_EQ(scene->bsdfs[2].Color("opacity", Vec3()).value.x, 0.25f);
  EXPECT_FLOAT_EQ(scene->bsdfs[3].Float("int_ior", 0), 1.5046f);

  ExpectError(Load("  <bsdf type=\"roughconductor\">\n    <float name=\"alpha\" value=\"0.1\"/>\n"
                   "    <float name=\"alpha_u\" value=\"0.1\"/>\n  </bsdf>\n"),
              "scene.xml:3:", "give either alpha or alpha_u/alpha_v");
  ExpectError(Load("  <bsdf type=\"conductor\">\n    <string name=\"material\" value=\"Au\"/>\n"
                   "    <rgb name=\"eta\" value=\"1\"/>\n  </bsdf>\n"),
              "scene.xml:3:", "give either material or eta/k");
  ExpectError(Load("  <bsdf type=\"roughplastic\">\n    <string name=\"distribution\" "
                   "value=\"phong\"/>\n  </bsdf>\n"),
              "scene.xml:3:", "unknown microfacet distribution 'phong'");
  ExpectError(Load("  <bsdf type=\"roughplastic\">\n    <float name=\"roughness\" "
                   "value=\"0.1\"/>\n  </bsdf>\n"),
              "scene.xml:3:", "unknown parameter 'roughness' for bsdf 'roughplastic'");
  ExpectError(Load("  <bsdf type=\"mask\">\n    <float name=\"opacity\" value=\"0.5\"/>\n"
                   "  </bsdf>\n"),
              "scene.xml:2:", "mask needs exactly one nested bsdf");
  // As Mitsuba 3.9.1 reads them: a distribution's name in any case; roughplastic's alpha_u and
  // alpha_v when equal, and an alpha below 1e-4 raised to it; material="none" beside eta/k.
  const auto loaded = Load(R"(  <bsdf type="roughplastic">
    <string name="distribution" value="GGX"/>
    <float name="alpha_u" value="0.2"/><float name="alpha_v" value="0.2"/>
  </bsdf>
  <bsdf type="roughplastic"><float name="alpha" value="0"/></bsdf>
  <bsdf type="roughconductor"><string name="distribution" value="Beckmann"/></bsdf>
  <bsdf type="conductor"><string name="material" value="none"/><rgb name="eta" value="0.2"/>
    <rgb name="k" value="3"/></bsdf>
)");
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  EXPECT_EQ(loaded->bsdfs[0].String("distribution", ""), "ggx");
  EXPECT_FLOAT_EQ(loaded->bsdfs[0].Float("alpha", 0), 0.2f);
  EXPECT_FLOAT_EQ(loaded->bsdfs[1].Float("alpha", 0), 1e-4f);
  EXPECT_EQ(loaded->bsdfs[2].String("distribution", ""), "beckmann");
  EXPECT_FLOAT_EQ(loaded->bsdfs[3].Color("k", Vec3()).value.x, 3.0f);
  ExpectError(Load("  <bsdf type=\"roughplastic\">\n    <float name=\"alpha_u\" value=\"0.1\"/>\n"
                   "    <float name=\"alpha_v\" value=\"0.2\"/>\n  </bsdf>\n"),
              "scene.xml:3:", "alpha_u and alpha_v must be equal");
  // Equal indices: Mitsuba refuses them too (every refracted sample would fail).
  ExpectError(
      Load("  <bsdf type=\"roughdielectric\">\n    <float name=\"int_ior\" value=\"1.2\"/>\n"
           "    <float name=\"ext_ior\" value=\"1.2\"/>\n  </bsdf>\n"),
      "scene.xml:3:", "int_ior and ext_ior must differ");
}

// principled: Mitsuba 3's parameter names, eta or specular (not both), file:line errors, and
// twosided refusing it when it transmits (as Mitsuba refuses transmissive nested BSDFs).
TEST(SceneLoaderTest, Principled) {
  const auto scene = Load(R"(  <bsdf type="principled">
    <rgb name="base_color" value="0.8, 0.2, 0.1"/>
    <float name="metallic" value="0.7"/>
    <float name="roughness" value="0.2"/>
    <float name="clearcoat" value="0.6"/>
    <float name="spec_trans" value="0.4"/>
    <float name="eta" value="1.33"/>
  </bsdf>
)");
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->bsdfs.size(), 1u);
  EXPECT_FLOAT_EQ(scene->bsdfs[0].Color("metallic", Vec3()).value.x, 0.7f);
  EXPECT_FLOAT_EQ(scene->bsdfs[0].Float("eta", 0), 1.33f);
  ExpectError(Load("  <bsdf type=\"principled\">\n    <float name=\"eta\" value=\"1.5\"/>\n"
                   "    <float name=\"specular\" value=\"0.5\"/>\n  </bsdf>\n"),
              "scene.xml:4:", "either eta or specular");
  ExpectError(Load("  <bsdf type=\"principled\">\n    <float name=\"alpha\" value=\"0.1\"/>\n"
                   "  </bsdf>\n"),
              "scene.xml:3:", "unknown parameter 'alpha' for bsdf 'principled'");
  ExpectError(Load("  <bsdf type=\"twosided\">\n    <bsdf type=\"principled\">\n"
                   "      <float name=\"spec_trans\" value=\"0.5\"/>\n    </bsdf>\n"
                   "  </bsdf>\n"),
              "scene.xml:2:", "twosided can only wrap a bsdf without transmission");
  EXPECT_TRUE(Load("  <bsdf type=\"twosided\">\n    <bsdf type=\"principled\">\n"
                   "      <float name=\"spec_trans\" value=\"0\"/>\n    </bsdf>\n"
                   "  </bsdf>\n")
                  .ok());
}

// principledthin: Mitsuba 3's parameters (its documentation's example, plus a textured
// diff_trans and the sampling rates), file:line errors for values outside the ranges Mitsuba
// documents and for parameters it does not have, and twosided refusing it (it transmits).
TEST(SceneLoaderTest, PrincipledThin) {
  const std::string dir = MakeDir("principledthin");
  fs::create_directories(dir + "/textures");
  WriteFile(dir + "/textures/leaf.png", "not decoded by the loader");
  const auto scene = Load(R"(  <bsdf type="principledthin">
    <rgb name="base_color" value="0.7,0.1,0.1 "/>
    <float name="roughness" value="0.15" />
    <float name="spec_tint" value="0.1" />
    <float name="anisotropic" value="0.5" />
    <float name="spec_trans" value="0.8" />
    <texture type="bitmap" name="diff_trans">
      <string name="filename" value="textures/leaf.png"/>
    </texture>
    <float name="eta" value="1.33" />
    <float name="sheen" value="0.2"/>
    <float name="sheen_tint" value="0.3"/>
    <float name="flatness" value="0.4"/>
    <float name="diffuse_transmittance_sampling_rate" value="2"/>
  </bsdf>
)",
                          dir + "/scene.xml");
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->bsdfs.size(), 1u);
  const BsdfDesc& d = scene->bsdfs[0];
  EXPECT_EQ(d.type, "principledthin");
  EXPECT_FLOAT_EQ(d.Color("base_color", Vec3()).value.y, 0.1f);
  EXPECT_FLOAT_EQ(d.Color("roughness", Vec3()).value.x, 0.15f);
  EXPECT_FLOAT_EQ(d.Color("spec_trans", Vec3()).value.x, 0.8f);
  EXPECT_FLOAT_EQ(d.Color("eta", Vec3()).value.x, 1.33f);
  EXPECT_FLOAT_EQ(d.Color("flatness", Vec3()).value.x, 0.4f);
  EXPECT_GE(d.Color("diff_trans", Vec3()).texture, 0);
  EXPECT_FLOAT_EQ(d.Float("diffuse_transmittance_sampling_rate", 0), 2.0f);
  ExpectError(Load("  <bsdf type=\"principledthin\">\n    <float name=\"diff_trans\" "
                   "value=\"2.5\"/>\n  </bsdf>\n"),
              "scene.xml:3:", "diff_trans must be in [0, 2], not 2.5");
  ExpectError(Load("  <bsdf type=\"principledthin\">\n    <float name=\"spec_trans\" "
                   "value=\"-0.1\"/>\n  </bsdf>\n"),
              "scene.xml:3:", "spec_trans must be in [0, 1]");
  ExpectError(Load("  <bsdf type=\"principledthin\">\n\n    <float name=\"eta\" "
                   "value=\"0\"/>\n  </bsdf>\n"),
              "scene.xml:4:", "eta must be at least");
  ExpectError(Load("  <bsdf type=\"principledthin\">\n    <float name=\"metallic\" "
                   "value=\"0.5\"/>\n  </bsdf>\n"),
              "scene.xml:3:", "unknown parameter 'metallic' for bsdf 'principledthin'");
  ExpectError(Load("  <bsdf type=\"principledthin\">\n    <float name=\"roughness\" "
                   "value=\"rough\"/>\n  </bsdf>\n"),
              "scene.xml:3:", "malformed number 'rough'");
  ExpectError(Load("  <bsdf type=\"twosided\">\n    <bsdf type=\"principledthin\"/>\n"
                   "  </bsdf>\n"),
              "scene.xml:2:", "twosided can only wrap a bsdf without transmission");
}

// normalmap and bumpmap: their texture and one nested bsdf are required (file:line errors).
TEST(SceneLoaderTest, NormalAndBumpMaps) {
  EXPECT_TRUE(Load("  <bsdf type=\"normalmap\">\n"
                   "    <rgb name=\"normalmap\" value=\"0.5, 0.5, 1\"/>\n"
                   "    <bsdf type=\"diffuse\"/>\n  </bsdf>\n")
                  .ok());
  ExpectError(Load("  <bsdf type=\"normalmap\">\n    <bsdf type=\"diffuse\"/>\n  </bsdf>\n"),
              "scene.xml:2:", "normalmap needs a 'normalmap' texture");
  ExpectError(Load("  <bsdf type=\"bumpmap\">\n    <bsdf type=\"diffuse\"/>\n  </bsdf>\n"),
              "scene.xml:2:", "bumpmap needs exactly one nested texture");
  ExpectError(Load("  <bsdf type=\"normalmap\">\n    <rgb name=\"normalmap\" value=\"0.5\"/>\n"
                   "  </bsdf>\n"),
              "scene.xml:2:", "normalmap needs exactly one nested bsdf");
}

// ---------------------------------------------------------------- materials and emitters

TEST(SceneLoaderTest, Materials) {
  const std::string dir = MakeDir("materials");
  fs::create_directories(dir + "/textures");
  WriteFile(dir + "/textures/wood.png", "not decoded by the loader");
  // The bitmap plugin's own choices, at the parameter's line.
  for (const char* bad : {"<string name=\"filter_type\" value=\"cubic\"/>",
                          "<string name=\"wrap_mode\" value=\"tile\"/>"}) {
    ExpectError(
        Load(std::string("  <texture type=\"bitmap\" id=\"w\">\n"
                         "    <string name=\"filename\" value=\"textures/wood.png\"/>\n    ") +
                 bad + "\n  </texture>\n",
             dir + "/scene.xml"),
        dir + "/scene.xml:4:",
        std::string(bad).find("cubic") != std::string::npos
            ? "unknown filter_type 'cubic' (supported: bilinear, nearest)"
            : "unknown wrap_mode 'tile' (supported: repeat, mirror, clamp)");
  }
  const auto scene = Load(R"(  <bsdf type="diffuse" id="red">
    <rgb name="reflectance" value="0.7, 0.1 0.1"/>
  </bsdf>
  <bsdf type="twosided" id="red-2s">
    <ref id="red"/>
  </bsdf>
  <texture type="bitmap" id="wood">
    <string name="filename" value="./textures/wood.png"/>
    <string name="filter_type" value="nearest"/>
    <boolean name="raw" value="true"/>
  </texture>
  <bsdf type="twosided" id="wood-2s">
    <bsdf type="diffuse">
      <ref name="reflectance" id="wood"/>
    </bsdf>
  </bsdf>
  <bsdf type="conductor" id="mirror">
    <string name="material" value="none"/>
    <rgb name="specular_reflectance" value="0.9"/>
  </bsdf>
  <bsdf type="dielectric" id="glass">
    <float name="int_ior" value="1.5"/>
    <string name="ext_ior" value="air"/>
  </bsdf>
  <bsdf type="thindielectric" id="thin">
    <string name="int_ior" value="water"/>
    <integer name="ext_ior" value="1"/>
  </bsdf>
  <shape type="cube"/>
  <shape type="cube"><ref id="wood-2s"/></shape>
)",
                          dir + "/scene.xml");
  ASSERT_TRUE(scene.ok()) << scene.status();
  // 6 + wood-2s's nested diffuse (added before it) + the default one of the first cube.
  ASSERT_EQ(scene->bsdfs.size(), 8u);
  const BsdfDesc& red2s = scene->bsdfs[1];
  EXPECT_EQ(red2s.id, "red-2s");
  EXPECT_EQ(red2s.type, "twosided");
  ASSERT_EQ(red2s.nested, std::vector<int>{0});
  EXPECT_EQ(scene->bsdfs[0].type, "diffuse");
  ExpectNear(scene->bsdfs[0].Color("reflectance", Vec3()).value, Vec3(0.7f, 0.1f, 0.1f));
  const BsdfDesc& wood = scene->bsdfs[3];
  EXPECT_EQ(wood.id, "wood-2s");
  EXPECT_EQ(wood.type, "twosided");
  ASSERT_EQ(wood.nested, std::vector<int>{2});
  ASSERT_EQ(scene->bsdfs[2].Color("reflectance", Vec3()).texture, 0);
  const TextureDesc& tex = scene->textures[0];
  EXPECT_EQ(fs::path(tex.filename), fs::path(dir) / "textures/wood.png");
  EXPECT_EQ(tex.filter_type, "nearest");
  EXPECT_EQ(tex.wrap_mode, "repeat");
  EXPECT_TRUE(tex.raw);
  EXPECT_EQ(scene->bsdfs[4].type, "conductor");
  ExpectNear(scene->bsdfs[4].Color("specular_reflectance", Vec3()).value, Vec3(0.9f));
  EXPECT_EQ(scene->bsdfs[5].type, "dielectric");
  EXPECT_FLOAT_EQ(scene->bsdfs[5].Float("int_ior", 0), 1.5f);
  EXPECT_FLOAT_EQ(scene->bsdfs[5].Float("ext_ior", 0), 1.000277f);
  EXPECT_EQ(scene->bsdfs[6].type, "thindielectric");
  EXPECT_FLOAT_EQ(scene->bsdfs[6].Float("int_ior", 0), 1.333f);
  EXPECT_FLOAT_EQ(scene->bsdfs[6].Float("ext_ior", 0), 1);
  // A shape without a bsdf gets diffuse 0.5, as in Mitsuba.
  const BsdfDesc& fallback = scene->bsdfs.at(scene->shapes.at(0).bsdf);
  EXPECT_EQ(fallback.type, "diffuse");
  ExpectNear(fallback.Color("reflectance", Vec3()).value, Vec3(0.5f));
  EXPECT_EQ(scene->shapes.at(1).bsdf, 3);

  ExpectError(Load("  <bsdf type=\"twosided\">\n    <bsdf type=\"dielectric\"/>\n  </bsdf>\n"),
              "scene.xml:2:", "twosided can only wrap");
  ExpectError(Load("  <bsdf type=\"dielectric\">\n    <string name=\"int_ior\" value=\"glas\"/>\n"
                   "  </bsdf>\n"),
              "scene.xml:3:", "unknown index of refraction 'glas'");
}

TEST(SceneLoaderTest, Emitters) {
  const auto scene = Load(R"(  <shape type="rectangle">
    <emitter type="area"><rgb name="radiance" value="1, 2, 3"/></emitter>
  </shape>
  <emitter type="point">
    <point name="position" x="1" y="2" z="3"/>
    <rgb name="intensity" value="5"/>
  </emitter>
  <emitter type="spot">
    <transform name="to_world"><lookat origin="0, 4, 0" target="0, 0, 0" up="0, 0, 1"/></transform>
    <float name="cutoff_angle" value="30"/>
  </emitter>
  <emitter type="directional">
    <vector name="direction" value="0, -2, 0"/>
    <rgb name="irradiance" value="9, 8, 7"/>
  </emitter>
  <emitter type="directional">
    <transform name="to_world"><rotate x="1" angle="90"/></transform>
  </emitter>
  <emitter type="constant"><rgb name="radiance" value="0.3, 0.4, 0.5"/></emitter>
)");
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_TRUE(scene->shapes.at(0).area_radiance.has_value());
  ExpectNear(*scene->shapes[0].area_radiance, Vec3(1, 2, 3));
  // An emitting shape without a bsdf reflects nothing (Mitsuba 3 gives it diffuse 0, where a
  // shape that does not emit gets 0.5): a large lamp that reflected half the light the floor
  // sends it made a floor under it 1.3% bright.
  const BsdfDesc& lamp = scene->bsdfs.at(scene->shapes[0].bsdf);
  EXPECT_EQ(lamp.type, "diffuse");
  ExpectNear(lamp.Color("reflectance", Vec3(-1)).value, Vec3(0));
  ASSERT_EQ(scene->emitters.size(), 5u);
  EXPECT_EQ(scene->emitters[0].type, "point");
  ExpectNear(scene->emitters[0].position, Vec3(1, 2, 3));
  ExpectNear(scene->emitters[0].intensity, Vec3(5));
  EXPECT_EQ(scene->emitters[1].type, "spot");
  ExpectNear(scene->emitters[1].position, Vec3(0, 4, 0));
  ExpectNear(scene->emitters[1].direction, Vec3(0, -1, 0));
  EXPECT_FLOAT_EQ(scene->emitters[1].cutoff_angle_deg, 30);
  EXPECT_FLOAT_EQ(scene->emitters[1].beam_width_deg, 22.5f);
  ExpectNear(scene->emitters[2].direction, Vec3(0, -1, 0));
  ExpectNear(scene->emitters[2].irradiance, Vec3(9, 8, 7));
  ExpectNear(scene->emitters[3].direction, Vec3(0, -1, 0));  // +z rotated 90 degrees about x
  EXPECT_EQ(scene->emitters[4].type, "constant");
  ExpectNear(scene->emitters[4].radiance, Vec3(0.3f, 0.4f, 0.5f));
  EXPECT_EQ(scene->emitters[4].loc.line, 20);

  // Mitsuba lights along to_world's +z unnormalised, so a scaled to_world scales a diffuse
  // surface's cosine: mitsuba 3.9.1 renders a white diffuse plane under look_at * scale(2) at
  // 0.63662, 0.31831 without the scale.
  const auto scaled = Load(R"(  <emitter type="directional">
    <transform name="to_world"><scale value="2"/><rotate x="1" angle="90"/></transform>
    <rgb name="irradiance" value="1, 2, 3"/>
  </emitter>
)");
  ASSERT_TRUE(scaled.ok()) << scaled.status();
  ExpectNear(scaled->emitters.at(0).direction, Vec3(0, -1, 0));
  ExpectNear(scaled->emitters.at(0).irradiance, Vec3(2, 4, 6));
  ExpectError(Load("  <emitter type=\"spot\">\n    <transform name=\"to_world\">"
                   "<scale z=\"0\"/></transform></emitter>\n"),
              "scene.xml:3:", "takes its axis (+z) to zero");
  const std::string dir = MakeDir("envmap_singular");
  WriteFile(dir + "/sky.exr", "not decoded by the loader");
  ExpectError(Load("  <emitter type=\"envmap\"><string name=\"filename\" value=\"sky.exr\"/>\n"
                   "    <transform name=\"to_world\"><scale y=\"0\"/></transform></emitter>\n",
                   dir + "/scene.xml"),
              dir + "/scene.xml:3:", "the envmap's to_world is singular");
  ExpectError(Load("  <emitter type=\"constant\"/>\n  <emitter type=\"constant\"/>\n"),
              "scene.xml:3:", "a second environment emitter (the first is at line 2)");
  ExpectError(Load("  <shape type=\"cube\">\n    <emitter type=\"point\"/>\n  </shape>\n"),
              "scene.xml:3:", "cannot be attached to a shape");
}

// Shapes and emitters are plugins found by their XML name (render/shapes/registry.h,
// render/emitters/registry.h): Mitsuba 3's names are all there, each loads from the XML with its
// defaults, and what an emitter plugin builds is the light the scene samples.
TEST(SceneLoaderTest, ShapeAndEmitterPluginsByName) {
  for (const char* name :
       {"obj", "ply", "serialized", "rectangle", "cube", "sphere", "disk", "cylinder"}) {
    const ShapePlugin* p = FindShapePlugin(name);
    ASSERT_NE(p, nullptr) << name;
    EXPECT_STREQ(p->name, name);
  }
  for (const char* name : {"rectangle", "cube", "sphere", "disk", "cylinder"}) {
    const auto scene = Load(absl::StrCat("  <shape type=\"", name, "\"/>\n"));
    ASSERT_TRUE(scene.ok()) << name << ": " << scene.status();
    ASSERT_EQ(scene->shapes.size(), 1u) << name;
    const ShapeDesc& s = scene->shapes[0];
    EXPECT_EQ(s.type == ShapeType::kSphere, std::string(name) == "sphere") << name;
    if (s.type != ShapeType::kSphere) {
      EXPECT_FALSE(s.mesh.indices.empty()) << name;
    }
  }
  EXPECT_EQ(FindShapePlugin("shapegroup"), nullptr);  // the loader's own, not a plugin
  const std::vector<std::string> emitters = EmitterPluginNames();
  EXPECT_EQ(absl::StrJoin(emitters, ","), "area,point,spot,directional,constant,envmap");
  for (const std::string& name : emitters) {
    const EmitterPlugin* p = FindEmitterPlugin(name);
    ASSERT_NE(p, nullptr) << name;
    EXPECT_EQ(p->build == nullptr, p->kind == EmitterPlugin::Kind::kArea) << name;
  }
  // Built lights: the plugin's type and values reach the scene's Light.
  const auto desc = Load(R"(  <emitter type="spot">
    <transform name="to_world"><lookat origin="0, 4, 0" target="0, 0, 0" up="0, 0, 1"/></transform>
    <rgb name="intensity" value="2, 3, 4"/>
    <float name="cutoff_angle" value="40"/>
  </emitter>
)");
  ASSERT_TRUE(desc.ok()) << desc.status();
  ASSERT_EQ(desc->emitters.size(), 1u);
  const EmitterPlugin* spot = FindEmitterPlugin(desc->emitters[0].type);
  ASSERT_NE(spot, nullptr);
  std::vector<std::unique_ptr<Texture>> textures;
  const absl::StatusOr<Light> light = spot->build(desc->emitters[0], &textures);
  ASSERT_TRUE(light.ok()) << light.status();
  EXPECT_EQ(light->type, LightType::kSpot);
  ExpectNear(light->intensity, Vec3(2, 3, 4));
  ExpectNear(light->direction, Vec3(0, -1, 0));
  EXPECT_NEAR(light->cos_cutoff, std::cos(40 * kPi / 180), 1e-6);
  EXPECT_NEAR(light->cos_beam, std::cos(30 * kPi / 180), 1e-6);  // beam_width: 3/4 of cutoff
  // The spot's bound at distance d: I / d^2 (what RecordBounds adds up).
  EXPECT_DOUBLE_EQ(spot->irradiance_bound(desc->emitters[0], 2.0), 1.0);
}

// A plugin's error about the element as a whole is at the element's line, not at the line of an
// unnamed object nested in it (its bsdf, its area emitter).
TEST(SceneLoaderErrorTest, ElementErrorsPointAtTheElement) {
  ExpectError(Load("  <shape type=\"cylinder\">\n"
                   "    <bsdf type=\"diffuse\"/>\n"
                   "    <point name=\"p1\" value=\"0, 0, 0\"/>\n"
                   "  </shape>\n"),
              "scene.xml:2:", "cylinder needs a positive radius and p0 != p1");
  ExpectError(Load("\n  <emitter type=\"point\">\n"
                   "    <point name=\"position\" value=\"0, 1, 0\"/>\n"
                   "    <transform name=\"to_world\"><translate y=\"1\"/></transform>\n"
                   "  </emitter>\n"),
              "scene.xml:3:", "give either position or to_world for a point emitter, not both");
}

TEST(SceneLoaderTest, IntegratorAndSampler) {
  const auto scene = LoadSceneString(R"(<scene version="3.0.0">
  <integrator type="irrcache">
    <integer name="max_depth" value="4"/>
    <integer name="rr_depth" value="3"/>
    <float name="error" value="0.15"/>
    <boolean name="gradients" value="true"/>
  </integrator>
  <sensor type="perspective">
    <sampler type="stratified">
      <integer name="sample_count" value="64"/>
    </sampler>
    <film type="hdrfilm"><rfilter type="box"/></film>
  </sensor>
</scene>
)",
                                     "s.xml", {});
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(scene->integrator.type, "irrcache");
  EXPECT_EQ(scene->integrator.max_depth, 4);
  EXPECT_EQ(scene->integrator.rr_depth, 3);
  const std::map<std::string, std::string> params = {{"error", "0.15"}, {"gradients", "true"}};
  EXPECT_EQ(scene->integrator.params, params);
  EXPECT_EQ(scene->camera.spp, 64);
  ASSERT_EQ(scene->warnings.size(), 1u);
  EXPECT_EQ(scene->warnings[0], "s.xml:9: sampler 'stratified' treated as independent");
  // The path integrator is strict.
  ExpectError(Load("  <integrator type=\"path\">\n    <float name=\"error\" value=\"0.1\"/>\n"
                   "  </integrator>\n"),
              "scene.xml:3:", "unknown parameter 'error' for integrator 'path'");
  // Mitsuba's `direct` (half of the public Mitsuba 3 scene collections use it) is path at
  // max_depth 2; its sample counts are read; a max_depth it does not have is an error, as there.
  const auto direct = Load(
      "  <integrator type=\"direct\"><integer name=\"emitter_samples\" value=\"4\"/>\n"
      "    <integer name=\"bsdf_samples\" value=\"2\"/></integrator>\n");
  ASSERT_TRUE(direct.ok()) << direct.status();
  EXPECT_EQ(direct->integrator.type, "path");
  EXPECT_EQ(direct->integrator.max_depth, 2);
  ExpectError(Load("  <integrator type=\"direct\">\n    <integer name=\"max_depth\" "
                   "value=\"5\"/>\n  </integrator>\n"),
              "scene.xml:3:", "unknown parameter 'max_depth' for integrator 'direct'");
}

// ---------------------------------------------------------------- meshes

TEST(SceneLoaderTest, BuiltInShapes) {
  const auto scene = Load(R"(  <shape type="rectangle">
    <transform name="to_world"><scale x="2"/><translate z="1"/></transform>
  </shape>
  <shape type="rectangle">
    <transform name="to_world"><scale x="-1"/></transform>
  </shape>
  <shape type="rectangle"><boolean name="flip_normals" value="true"/></shape>
  <shape type="cube"/>
  <shape type="disk"><boolean name="face_normals" value="true"/></shape>
)");
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->shapes.size(), 5u);
  const auto geometric_normal = [](const TriangleMesh& m, size_t t) {
    const Vec3& p0 = m.positions[m.indices[3 * t]];
    return Normalize(
        Cross(m.positions[m.indices[3 * t + 1]] - p0, m.positions[m.indices[3 * t + 2]] - p0));
  };
  const TriangleMesh& rect = scene->shapes[0].mesh;
  ASSERT_EQ(rect.indices.size(), 6u);
  ExpectNear(rect.positions[2], Vec3(2, 1, 1));
  ExpectNear(geometric_normal(rect, 0), Vec3(0, 0, 1));
  ExpectNear(rect.normals[0], Vec3(0, 0, 1));
  // Mirrored rectangle: Mitsuba's normal is still +z, so the winding turns with the mirror.
  ExpectNear(geometric_normal(scene->shapes[1].mesh, 1), Vec3(0, 0, 1));
  ExpectNear(geometric_normal(scene->shapes[2].mesh, 0), Vec3(0, 0, -1));
  ExpectNear(scene->shapes[2].mesh.normals[0], Vec3(0, 0, -1));
  EXPECT_TRUE(scene->shapes[2].flip_normals);
  const TriangleMesh& cube = scene->shapes[3].mesh;
  EXPECT_EQ(cube.positions.size(), 24u);
  ASSERT_EQ(cube.indices.size(), 36u);
  for (size_t t = 0; t < 12; ++t) {  // outward: the normal points the way of the face centre
    const Vec3 centre =
        (cube.positions[cube.indices[3 * t]] + cube.positions[cube.indices[3 * t + 1]] +
         cube.positions[cube.indices[3 * t + 2]]) /
        3.0f;
    EXPECT_GT(Dot(geometric_normal(cube, t), centre), 0.3f) << "triangle " << t;
    EXPECT_NEAR(Dot(geometric_normal(cube, t), cube.normals[cube.indices[3 * t]]), 1, 1e-5);
  }
  const TriangleMesh& disk = scene->shapes[4].mesh;
  EXPECT_EQ(disk.indices.size(), 3u * 128);
  EXPECT_TRUE(disk.normals.empty());  // face_normals
  ExpectNear(geometric_normal(disk, 5), Vec3(0, 0, 1));
}

TEST(SceneLoaderTest, LoadsObj) {
  const std::string dir = MakeDir("obj");
  WriteFile(dir + "/meshes/quad.obj", R"(# a quad as one polygon, all corner forms
o quad
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 0.25
vn 0 0 1
f 1/1/1 2/2/1 -2/3/-1 -1/3/1
s off
)");
  WriteFile(dir + "/meshes/plain.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nf 1 2 3\nf 1 4 5\n");
  WriteFile(dir + "/meshes/mixed.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n"
            "f 1//1 2//1 3//1\nf 1/1 2/1 3/1\n");
  const auto scene = Load(R"(  <shape type="obj">
    <string name="filename" value="meshes/quad.obj"/>
    <transform name="to_world"><translate x="10"/></transform>
  </shape>
  <shape type="obj">
    <string name="filename" value="meshes/plain.obj"/>
  </shape>
  <shape type="obj">
    <string name="filename" value="meshes/mixed.obj"/>
    <boolean name="face_normals" value="true"/>
  </shape>
)",
                          dir + "/scene.xml");
  ASSERT_TRUE(scene.ok()) << scene.status();
  const TriangleMesh& quad = scene->shapes.at(0).mesh;
  ASSERT_EQ(quad.indices.size(), 6u);  // fan of 2 triangles
  ASSERT_EQ(quad.positions.size(), 4u);
  ExpectNear(quad.positions[quad.indices[2]], Vec3(11, 1, 0));
  ASSERT_EQ(quad.uvs.size(), 8u);
  EXPECT_FLOAT_EQ(quad.uvs[2 * quad.indices[2] + 1], 0.75f);  // v flipped: 1 - 0.25
  ASSERT_EQ(quad.normals.size(), 4u);
  ExpectNear(quad.normals[0], Vec3(0, 0, 1));

  // No normals, no face_normals: smooth angle-weighted normals, as Mitsuba computes them.
  const TriangleMesh& plain = scene->shapes.at(1).mesh;
  // The faces (normals +z and +y, equal areas) meet vertex 0 at 90 and 45 degrees: weights 2 : 1
  // (area weighting would give 1 : 1).
  ASSERT_EQ(plain.normals.size(), 5u);
  ExpectNear(plain.normals[0], Normalize(Vec3(0, 1, 2)));
  ExpectNear(plain.normals[1], Vec3(0, 0, 1));
  ExpectNear(plain.normals[3], Vec3(0, 1, 0));

  // Some corners lack vt: no uvs; face_normals: no normals.
  const TriangleMesh& mixed = scene->shapes.at(2).mesh;
  EXPECT_TRUE(mixed.uvs.empty());
  EXPECT_TRUE(mixed.normals.empty());
  EXPECT_EQ(mixed.indices.size(), 6u);

  WriteFile(dir + "/meshes/bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 nan\nf 1 2 3\n");
  ExpectError(Load("  <shape type=\"obj\">\n    <string name=\"filename\" "
                   "value=\"meshes/bad.obj\"/>\n  </shape>\n",
                   dir + "/scene.xml"),
              dir + "/scene.xml:2:", "bad.obj:3: non-finite number 'nan'");
}

// A binary little-endian PLY with normals and uvs: a quad (fan) and a triangle.
std::string BinaryPly(uint32_t last_index) {
  std::string ply =
      "ply\nformat binary_little_endian 1.0\ncomment test\nelement vertex 4\n"
      "property float x\nproperty float y\nproperty float z\nproperty float nx\n"
      "property float ny\nproperty float nz\nproperty uchar red\nproperty float u\n"
      "property float v\nelement face 2\nproperty list uint8 uint vertex_indices\nend_header\n";
  const auto put = [&ply](const void* data, size_t size) {
    ply.append(static_cast<const char*>(data), size);
  };
  const float xy[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  for (const auto& [x, y] : xy) {
    const float values[6] = {x, y, 0, 0, 0, 1};
    put(values, sizeof(values));
    ply.push_back('\x7f');
    const float uv[2] = {x, y};
    put(uv, sizeof(uv));
  }
  const uint32_t quad[4] = {0, 1, 2, 3}, tri[3] = {0, 2, last_index};
  ply.push_back('\x04');
  put(quad, sizeof(quad));
  ply.push_back('\x03');
  put(tri, sizeof(tri));
  return ply;
}

TEST(SceneLoaderTest, LoadsPly) {
  uint32_t probe = 1;
  char first_byte;
  std::memcpy(&first_byte, &probe, 1);
  if (first_byte != 1) GTEST_SKIP() << "the test writes PLY data in host byte order";
  const std::string dir = MakeDir("ply");
  WriteFile(dir + "/meshes/binary.ply", BinaryPly(3));
  WriteFile(dir + "/meshes/ascii.ply",
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
            "property double z\nelement face 1\nproperty list uchar int vertex_indices\n"
            "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  const auto scene = Load(R"(  <shape type="ply">
    <string name="filename" value="meshes/binary.ply"/>
    <transform name="to_world"><rotate x="1" angle="180"/></transform>
  </shape>
  <shape type="ply">
    <string name="filename" value="meshes/ascii.ply"/>
    <boolean name="face_normals" value="true"/>
  </shape>
)",
                          dir + "/scene.xml");
  ASSERT_TRUE(scene.ok()) << scene.status();
  const TriangleMesh& bin = scene->shapes.at(0).mesh;
  ASSERT_EQ(bin.indices.size(), 9u);
  ASSERT_EQ(bin.positions.size(), 4u);
  ExpectNear(bin.positions[2], Vec3(1, -1, 0));
  ExpectNear(bin.normals[2], Vec3(0, 0, -1));
  ASSERT_EQ(bin.uvs.size(), 8u);
  EXPECT_FLOAT_EQ(bin.uvs[5], 1);  // PLY uvs are not flipped
  const std::vector<uint32_t> expected = {0, 1, 2, 0, 2, 3, 0, 2, 3};
  EXPECT_EQ(bin.indices, expected);
  EXPECT_EQ(scene->shapes.at(1).mesh.indices.size(), 3u);
  EXPECT_TRUE(scene->shapes.at(1).mesh.normals.empty());
  // flip_tex_coords, as Mitsuba's ply reads it (off by default): v becomes 1 - v.
  const auto flipped = Load(R"(  <shape type="ply">
    <string name="filename" value="meshes/binary.ply"/>
    <boolean name="flip_tex_coords" value="true"/>
  </shape>
)",
                            dir + "/scene.xml");
  ASSERT_TRUE(flipped.ok()) << flipped.status();
  ASSERT_EQ(flipped->shapes.at(0).mesh.uvs.size(), 8u);
  for (size_t i = 0; i < 8; ++i)
    EXPECT_FLOAT_EQ(flipped->shapes.at(0).mesh.uvs[i], i % 2 ? 1 - bin.uvs[i] : bin.uvs[i]) << i;

  WriteFile(dir + "/meshes/binary.ply", BinaryPly(4));
  ExpectError(Load("  <shape type=\"ply\">\n    <string name=\"filename\" "
                   "value=\"meshes/binary.ply\"/>\n  </shape>\n",
                   dir + "/scene.xml"),
              dir + "/scene.xml:2:", "binary.ply: face 1: vertex index 4 out of range");
  WriteFile(dir + "/meshes/binary.ply", BinaryPly(3).substr(0, BinaryPly(3).size() - 5));
  ExpectError(Load("  <shape type=\"ply\">\n    <string name=\"filename\" "
                   "value=\"meshes/binary.ply\"/>\n  </shape>\n",
                   dir + "/scene.xml"),
              dir + "/scene.xml:2:", "truncated");
}

TEST(SceneLoaderTest, DropsDegenerateTriangles) {
  const std::string dir = MakeDir("degenerate");
  WriteFile(dir + "/meshes/mix.obj", R"(v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 0
v 2 0 0
v 0.1 0.1 0.5
v 0.2 0.2 0.5
v 0.4 0.4 0.5
v 1 0.001 0
f 1 2 3
f 1 1 2
f 1 4 2
f 1 2 5
f 6 7 8
f 1 2 9
)");
  WriteFile(dir + "/meshes/none.obj", "v 0 0 0\nv 1 1 1\nf 1 2 2\n");
  const auto scene = Load(R"(  <shape type="obj" id="mix">
    <string name="filename" value="meshes/mix.obj"/>
    <boolean name="face_normals" value="true"/>
  </shape>
  <shape type="obj" id="none">
    <string name="filename" value="meshes/none.obj"/>
  </shape>
)",
                          dir + "/scene.xml");
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->shapes.size(), 1u);  // "none" has nothing left and is skipped
  const ShapeDesc& mix = scene->shapes[0];
  // Kept: the right triangle and the thin (1 x 0.001) but proper sliver.
  EXPECT_EQ(mix.mesh.indices.size(), 6u);
  EXPECT_EQ(mix.degenerate_dropped, 4);
  ASSERT_EQ(scene->warnings.size(), 3u);
  EXPECT_EQ(scene->warnings[0].rfind(dir + "/scene.xml:2: shape 'mix': dropped 4 degenerate", 0),
            0u)
      << scene->warnings[0];
  EXPECT_NE(scene->warnings[2].find("'none' has no triangles left"), std::string::npos);
}

// ---------------------------------------------------------------- the shipped scenes

// The folder holding scenes/<name>/scene.xml: $IRFARM_TEST_DATA, else the compiled-in
// IRFARM_TEST_DATA (the repository's tests/data: nothing outside the clone).
std::string ScenesRoot() {
  std::vector<std::string> candidates;
  if (const char* env = std::getenv("IRFARM_TEST_DATA")) candidates.push_back(env);
  candidates.push_back(IRFARM_TEST_DATA);
  for (const std::string& c : candidates) {
    std::error_code ec;
    if (fs::is_directory(fs::path(c) / "scenes", ec)) return c + "/scenes";
  }
  return "";
}

TEST(SceneLoaderTest, LoadsEveryTestScene) {
  const std::string root = ScenesRoot();
  ASSERT_FALSE(root.empty()) << "no scenes folder under IRFARM_TEST_DATA";
  std::vector<fs::path> files;
  for (const fs::directory_entry& d : fs::directory_iterator(root)) {
    if (fs::is_regular_file(d.path() / "scene.xml")) files.push_back(d.path() / "scene.xml");
  }
  std::sort(files.begin(), files.end());
  ASSERT_FALSE(files.empty()) << "no <name>/scene.xml under " << root;
  for (const fs::path& file : files) {
    SCOPED_TRACE(file.string());
    const auto scene = LoadSceneFile(file.string(), {});
    ASSERT_TRUE(scene.ok()) << scene.status();
    size_t triangles = 0;
    int emitters = int(scene->emitters.size());
    for (const ShapeDesc& s : scene->shapes) {
      triangles += s.mesh.indices.size() / 3;
      emitters += s.area_radiance.has_value();
      EXPECT_GE(s.bsdf, 0);
      EXPECT_LT(s.bsdf, int(scene->bsdfs.size()));
      for (uint32_t i : s.mesh.indices) ASSERT_LT(i, s.mesh.positions.size());
      EXPECT_TRUE(s.mesh.normals.empty() || s.mesh.normals.size() == s.mesh.positions.size());
    }
    EXPECT_GT(scene->shapes.size(), 0u);
    EXPECT_GT(triangles, 0u);
    EXPECT_GT(emitters, 0);
    const CameraDesc& cam = scene->camera;
    EXPECT_GT(cam.fov_x_deg, 1);
    EXPECT_LT(cam.fov_x_deg, 179);
    EXPECT_GT(cam.width, 0);
    EXPECT_GT(cam.height, 0);
    EXPECT_GT(cam.spp, 0);
    for (int j = 0; j < 3; ++j) {  // a rotation: unit, orthogonal axes, right-handed with left
      EXPECT_NEAR(Length(Column(cam.to_world, j)), 1, 1e-4);
      EXPECT_NEAR(Dot(Column(cam.to_world, j), Column(cam.to_world, (j + 1) % 3)), 0, 1e-4);
    }
    EXPECT_TRUE(IsFinite(Column(cam.to_world, 3)));
    std::cout << file.parent_path().filename().string() << ": " << scene->shapes.size()
              << " shapes, " << triangles << " triangles, " << emitters << " emitters, fov_x "
              << cam.fov_x_deg << ", " << cam.width << " x " << cam.height << ", spp " << cam.spp
              << ", " << scene->warnings.size() << " warnings\n";
  }
}

}  // namespace
}  // namespace irfarm

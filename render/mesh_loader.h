// Triangle meshes for the scene loader: reads Wavefront OBJ and PLY files (Mitsuba's serialized
// format: serialized_mesh.h), generates the built-in shapes (rectangle, cube, disk, cylinder) and
// cleans meshes up (world transform, degenerate triangles, smooth normals). Meshes come out in
// object space; TransformMesh moves them to world space. Errors are statuses whose message is
// "FILE:LINE: what is wrong" (OBJ, PLY header) or "FILE: what is wrong" (PLY data, which has no
// lines); NOT_FOUND when the file cannot be read.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "core/math.h"
#include "render/scene_desc.h"

namespace irfarm {

// The bytes of the file at `path`; NOT_FOUND ("PATH: cannot open file") when it cannot be read.
// The mesh readers' (OBJ, PLY, serialized) shared way in.
absl::StatusOr<std::string> ReadWholeFile(const std::string& path);

// Parses OBJ text: `v`, `vt`, `vn` and `f` with `a`, `a/b`, `a//c` or `a/b/c` corners (1-based, or
// negative = relative to the end of the list so far); polygons become triangle fans; other
// statements are ignored. Corners with the same (v, vt, vn) share one output vertex, as in
// Mitsuba. uvs (normals) are kept only if every corner has a vt (vn). flip_v stores each vt as
// (u, 1 - v) (Mitsuba's flip_tex_coords, on by default). Every index is checked: one out of range
// is an error naming the line of its face. `path` is only used in error messages.
absl::StatusOr<TriangleMesh> ParseObjMesh(const std::string& text, const std::string& path,
                                          bool flip_v = true);
absl::StatusOr<TriangleMesh> LoadObjMesh(const std::string& path, bool flip_v = true);

// Reads a PLY file: format ascii, binary_little_endian or binary_big_endian 1.0; vertex properties
// x y z (any scalar type), optional nx ny nz and u v (or s t, texture_u texture_v); faces as a
// list property `vertex_indices` (or `vertex_index`) of any integer types, polygons as fans.
// Other properties and elements are skipped. An index >= the vertex count is an error.
absl::StatusOr<TriangleMesh> LoadPlyMesh(const std::string& path);

// Built-in shapes, object space, counter-clockwise seen from the front, with per-vertex normals
// and uvs. Rectangle: [-1,1]^2 in z = 0, normal +z, uv = (x + 1) / 2, (y + 1) / 2.
// Cube: [-1,1]^3, 24 vertices and 12 triangles, outward face normals.
// Disk: unit disk in z = 0, normal +z, `segments` triangles, uv = (r, angle / 2pi) as in Mitsuba.
TriangleMesh MakeRectangleMesh();
TriangleMesh MakeCubeMesh();
TriangleMesh MakeDiskMesh(int segments = 128);
// Cylinder: Mitsuba's open tube of radius 1 around z, z in [0, 1] (no caps), outward normals
// (exact, per vertex: the tube's shading is smooth), uv = (angle / 2pi, z); `segments` quads, each
// two triangles, with one seam column so u runs 0 ... 1, split along z into `rings` equal rings
// (the same surface: the tube is straight along z). The polygon is inscribed in the circle: at
// kCylinderSegments its area is 1 - 2.5e-5 of the tube's.
constexpr int kCylinderSegments = 256;
TriangleMesh MakeCylinderMesh(int segments = kCylinderSegments, int rings = 1);
// Rings for a tube of this length and radius: one per kCylinderRingRadii radii of length (1 to
// kMaxCylinderRings). An emitting tube's triangles are then a few radii long instead of slivers
// its full length, so its light tree bounds where along the tube they lie (distance and
// horizon), and far from the tube they are sampled by area. Measured on three rooms with tube
// lamps (make_room 905 and 910, tests/data mesh-lamps; irrcache defaults and `path` 16 spp,
// seeds 7-8, 1, 4, 8 and 16 rings; docs/bench/unseen-rooms-2026-12-06/ab-cylinder-rings.txt):
// 8 rings (2.3 to 5.8 radii long) were best or within 5% of the best everywhere, at 7-26% more
// CPU for 20-45% less error.
constexpr float kCylinderRingRadii = 4.0f;
constexpr int kMaxCylinderRings = 64;
int CylinderRings(float length, float radius);
// The same for emitting meshes read from files (obj, ply, serialized): a tube modelled in Blender
// has one ring too. SliceAlongPrincipalAxis cuts each connected part of the mesh by planes across
// the part's principal axis (the line through its surface's centroid along the leading
// eigenvector of its covariance), spaced kCylinderRingRadii times the largest distance of a
// vertex from that axis (a tube's radius, a strip's half width). Each triangle becomes the convex
// pieces the slabs cut from it, fanned into triangles; a cut point on an edge two triangles share
// is one vertex, so the mesh stays watertight where it was, and its normals and uvs interpolate as
// before. Stops (leaving the mesh as it was) where the slices would make more than max_triangles.
// Returns the triangles added.
int SliceAlongPrincipalAxis(TriangleMesh* mesh, size_t max_triangles);

// Positions by to_world, normals by its inverse transpose (normalized). The index order is kept,
// as Mitsuba does: a mirroring transform (negative determinant) turns the geometric normal
// cross(p1 - p0, p2 - p0) around.
void TransformMesh(const Mat4& to_world, TriangleMesh* mesh);

// Reverses the winding of every triangle (normals untouched).
void ReverseWinding(TriangleMesh* mesh);

// flip_normals: reverses the winding and negates the vertex normals.
void FlipNormals(TriangleMesh* mesh);

// Removes triangles with a repeated index, a non-finite vertex or (near) zero area: the sine of
// the angle at the first vertex below 1e-6. Returns how many were removed. Vertices are kept.
int DropDegenerateTriangles(TriangleMesh* mesh);

// Smooth per-vertex normals as Mitsuba 3 computes them for a mesh that has none: the unit face
// normals of the incident triangles weighted by the triangle's angle at the vertex (Thuermer and
// Wuethrich 1998). Call on world-space positions; unreferenced vertices get (1, 0, 0).
void ComputeSmoothNormals(TriangleMesh* mesh);

}  // namespace irfarm

// One triangle of an emissive mesh, as the light sampler keeps it (its own copy of the geometry).
#pragma once

#include "core/math.h"

namespace irfarm {

struct LightTriangle {
  Vec3 p0, p1, p2;
  Vec3 ng;          // unit geometric normal: the emitting side
  Vec3 n0, n1, n2;  // vertex normals (shading); equal to ng when the mesh has none
  float area = 0;
  float error_scale = 0;  // magnitude of the vertex coordinates (ray offsets)
};

}  // namespace irfarm

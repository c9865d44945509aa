// A ray: points origin + t dir for t in [tnear, tmax]. Camera rays start and end at the sensor's
// clip distances (Camera::Clip); every other ray starts at its origin (tnear 0), which
// Scene::SpawnRay has already moved off the surface it leaves.
#pragma once

#include <cmath>

#include "core/math.h"

namespace irfarm {

struct Ray {
  Vec3 origin, dir;
  float tmax = INFINITY;
  float tnear = 0;
};

}  // namespace irfarm

// Auxiliary output variables (AOVs): per-pixel images accumulated from the very camera samples
// that make the image, written as extra layers of the output EXR ("albedo.R", "normal.X", ...)
// and used to guide the denoiser (render/denoiser.h). Per pixel, the mean over its samples of:
//   albedo    beta * reflectance of the first non-specular surface the camera path reaches
//             (through mirrors and glass, with their tint), as Open Image Denoise expects;
//             black where the path escapes or ends before a diffuse surface.
//   normal    that surface's shading normal, turned towards the viewer (world space); zero where
//             there is none.
//   depth     distance along the camera path (through specular bounces) to that surface, in
//             scene units; 0 where there is none.
//   emission  light emitted by what the camera sees directly or through specular surfaces
//             (including the sky); it is part of `direct`.
//   direct    emission + light reaching the first diffuse surface straight from a light
//             (irrcache: its explicit next-event estimate; path: next-event estimation and the
//             MIS-weighted light hit by the BSDF ray at that surface).
//   indirect  everything else (irrcache: the cached irradiance term); direct + indirect = image.
//   variance  per channel, the variance of the pixel's mean estimate (sample variance / n).
// A sample the renderer drops (non-finite) counts as black here too, as in the image.
#pragma once

#include <string>
#include <vector>

#include "render/image.h"

namespace irfarm {

// What one camera sample contributes to the AOVs; integrators fill it when given one.
struct SampleAov {
  Vec3 emission, direct, indirect;  // direct includes emission; L = direct + indirect
  Vec3 albedo, normal;
  float depth = 0;
};

// One pixel's running sums over its camera samples. Variance sums are in double: sum L^2 - n
// mean^2 cancels badly in float for bright, low-noise pixels.
struct PixelAovSum {
  Vec3 emission, direct, indirect, albedo, normal;
  double depth = 0;
  double sum[3] = {0, 0, 0}, sum_sq[3] = {0, 0, 0};

  // `L` is the sample's radiance as it went into the image (finite).
  void Add(const Vec3& L, const SampleAov& a) {
    emission += a.emission;
    direct += a.direct;
    indirect += a.indirect;
    albedo += a.albedo;
    normal += a.normal;
    depth += a.depth;
    for (int c = 0; c < 3; ++c) {
      sum[c] += L[c];
      sum_sq[c] += double(L[c]) * L[c];
    }
  }
};

// The AOV images of a rendered rectangle (all the same size as the image).
struct AovImages {
  Image albedo, normal, depth, emission, direct, indirect, variance;  // depth: x only

  AovImages() = default;
  AovImages(int w, int h);
  bool empty() const { return albedo.pixels.empty(); }
  // Stores pixel (x, y) from its sums over `n` samples (the pixel's spp, dropped ones included).
  void Set(int x, int y, const PixelAovSum& s, int n);
  // The EXR layers, named as OpenEXR tools expect ("albedo" with R, G, B; "normal" with X, Y, Z;
  // "depth" with Z; ...).
  std::vector<ExrLayer> Layers() const;
  // Reads every layer Layers() names from `path`.
  static absl::StatusOr<AovImages> Read(const std::string& path);
};

}  // namespace irfarm

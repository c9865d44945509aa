// The perspective camera of Mitsuba 3: camera space looks along +z with +y up and +x to the
// image's left; the ray through film point (x, y) (pixels, row 0 at the top) has direction
// f + (2x/w - 1) tan(fov_x/2) r + (1 - 2y/h) tan(fov_y/2) u with r = -column0 (image right).
// It carries the film's reconstruction filter, which places each camera sample on the film.
#pragma once

#include <cmath>

#include "core/ray.h"
#include "render/pixel_filter.h"
#include "render/sampling.h"
#include "render/scene_desc.h"

namespace irfarm {

class Camera {
 public:
  Camera() = default;
  explicit Camera(const CameraDesc& d)
      : width_(d.width),
        height_(d.height),
        film_w_(d.film_width > 0 ? d.film_width : d.width),
        film_h_(d.film_height > 0 ? d.film_height : d.height),
        // The crop window's corner in film pixels, moved by the principal point's offset.
        crop_x_(float(d.crop_x) + d.principal_x * float(film_w_)),
        crop_y_(float(d.crop_y) + d.principal_y * float(film_h_)),
        filter_(d.filter, d.width, d.height) {
    origin_ = d.to_world.ApplyPoint(Vec3(0, 0, 0));
    forward_ = Normalize(d.to_world.ApplyVector(Vec3(0, 0, 1)));
    right_ = Normalize(d.to_world.ApplyVector(Vec3(-1, 0, 0)));
    up_ = Normalize(d.to_world.ApplyVector(Vec3(0, 1, 0)));
    tan_x_ = std::tan(d.fov_x_deg * kPi / 360.0f);
    aperture_radius_ = d.aperture_radius;
    focus_distance_ = d.focus_distance;
    near_clip_ = d.near_clip;
    far_clip_ = d.far_clip;
    tan_y_ = tan_x_ * float(film_h_) / float(film_w_);
  }
  // Unit direction of the ray through image point (x, y) in pixels (of the crop window).
  Vec3 Direction(float x, float y) const {
    x += crop_x_;
    y += crop_y_;
    return Normalize(forward_ + right_ * ((2 * x / film_w_ - 1) * tan_x_) +
                     up_ * ((1 - 2 * y / film_h_) * tan_y_));
  }
  // thinlens (Mitsuba 3's): the ray of film direction `dir` (from Direction) through a lens point
  // uniform on the aperture disk (u then v drawn from rng), aimed at where the pinhole ray meets
  // the plane in focus. A pinhole camera returns the pinhole ray and draws nothing.
  bool has_lens() const { return aperture_radius_ > 0; }
  void LensRay(const Vec3& dir, Rng& rng, Vec3* origin, Vec3* direction) const {
    if (!has_lens()) {
      *origin = origin_;
      *direction = dir;
      return;
    }
    const Vec3 focus = origin_ + dir * (focus_distance_ / Dot(dir, forward_));
    const float u = rng.Next(), v = rng.Next();
    float dx, dy;
    ConcentricDisk(u, v, &dx, &dy);
    *origin = origin_ + right_ * (dx * aperture_radius_) + up_ * (dy * aperture_radius_);
    *direction = Normalize(focus - *origin);
  }
  // The camera ray from `origin` (the pinhole or a lens point) along unit `dir`, clipped as
  // Mitsuba 3's sensors clip: it starts where the view axis reaches near_clip and ends where it
  // reaches far_clip (t = clip / (dir . forward)). Geometry nearer or farther is not seen.
  Ray Clip(const Vec3& origin, const Vec3& dir) const {
    const float c = Dot(dir, forward_);
    if (!(c > 0)) return Ray{origin, dir, INFINITY, 0};
    return Ray{origin, dir, far_clip_ / c, near_clip_ / c};
  }
  // The pinhole's ray through film direction `dir` (from Direction), clipped.
  Ray PinholeRay(const Vec3& dir) const { return Clip(origin_, dir); }
  // The ray of film direction `dir` through the lens (LensRay), clipped.
  Ray SampleRay(const Vec3& dir, Rng& rng) const {
    Vec3 origin, direction;
    LensRay(dir, rng, &origin, &direction);
    return Clip(origin, direction);
  }
  // Unit direction of camera sample (u, v) in [0, 1)^2 of pixel (px, py) that stays in its pixel:
  // its film point is drawn from the pixel's filter (PixelFilter::FilmPoint), so the pixel's
  // value is the plain mean of its samples whatever the integrator. (Splatted samples land at
  // (px + u, py + v): Direction.)
  Vec3 SampleDirection(int px, int py, float u, float v) const {
    float x, y;
    filter_.FilmPoint(px, py, u, v, &x, &y);
    return Direction(x, y);
  }
  // The inverse of Direction: the image point (x, y) in pixels (of the crop window) whose ray
  // passes through world point `p`. False when p is not in front of the camera (or the camera
  // basis is degenerate); x, y may then be anything and may lie outside the image otherwise.
  // Solves p - origin = t (forward + a right + b up) in the camera basis (Cramer's rule, so a
  // to_world with scale or shear inverts exactly too); used by the dashboard's record map.
  bool Project(const Vec3& p, float* x, float* y) const {
    const Vec3 d = p - origin_;
    const float det = Dot(forward_, Cross(right_, up_));
    if (!(std::fabs(det) > 1e-12f)) return false;
    const float t = Dot(d, Cross(right_, up_)) / det;
    if (!(t > 0)) return false;
    const float a = Dot(forward_, Cross(d, up_)) / det / t;
    const float b = Dot(forward_, Cross(right_, d)) / det / t;
    *x = (a / tan_x_ + 1) * 0.5f * film_w_ - crop_x_;
    *y = (1 - b / tan_y_) * 0.5f * film_h_ - crop_y_;
    return std::isfinite(*x) && std::isfinite(*y);
  }
  const PixelFilter& filter() const { return filter_; }
  const Vec3& origin() const { return origin_; }
  int width() const { return width_; }
  int height() const { return height_; }
  // Width of one pixel's footprint on a surface at distance d straight ahead (scene units).
  float PixelSpread(float distance) const { return distance * 2 * tan_x_ / film_w_; }

 private:
  int width_ = 1, height_ = 1;
  int film_w_ = 1, film_h_ = 1;
  float crop_x_ = 0, crop_y_ = 0;
  PixelFilter filter_;
  Vec3 origin_, forward_{0, 0, 1}, right_{-1, 0, 0}, up_{0, 1, 0};
  float tan_x_ = 1, tan_y_ = 1;
  float aperture_radius_ = 0, focus_distance_ = 1e4f;
  float near_clip_ = 0, far_clip_ = INFINITY;
};

}  // namespace irfarm

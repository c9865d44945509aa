#include "render/record_balance.h"

#include <algorithm>
#include <cmath>

namespace irfarm {

BalanceResult ChooseRecordRays(const PilotFigures& pilot, const BalanceInputs& in) {
  BalanceResult r;
  const int r0 = std::max(1, in.record_rays);
  r.record_rays = r0;
  const size_t k = pilot.pixels.size();
  if (k == 0 || pilot.samples <= 0 || pilot.records == 0 || pilot.sample_count == 0) return r;
  double noise = 0, per_px = 0, per_sample_error = 0;
  std::vector<double> errors;
  errors.reserve(k);
  for (const PilotPixel& p : pilot.pixels) {
    if (p.has_record) {
      noise += p.record_noise;
      per_px += p.records_per_px;
    }
    // The pixel's error at one sample: relMSE falls as 1 / samples.
    errors.push_back(p.sampling_error * pilot.samples);
  }
  // The sampling error without the pilot's largest kTrimmed of pixels: one firefly among a
  // hundred pixels would otherwise decide the rays (on living-room the pilot's mean ranged 2.8x
  // over three seeds); the image's fireflies are no reason to make records noisier either.
  per_sample_error = TrimmedMean(std::move(errors));
  noise /= double(k);
  per_px /= double(k);
  r.record_noise = noise;

  // Samples adaptive sampling will take: min_spp everywhere, then doubling where the error is,
  // until the image's estimate reaches the goal (relMSE ~ 1 / spp) or max_spp.
  const int max_spp = std::max(1, in.max_spp);
  const int min_spp = in.adaptive ? std::clamp(in.min_spp, 1, max_spp) : max_spp;
  double spp = max_spp;
  if (in.adaptive && in.sampling_goal > 0)
    spp = std::clamp(per_sample_error / in.sampling_goal, double(min_spp), double(max_spp));
  r.expected_spp = spp;
  r.sampling_error = per_sample_error / spp;

  const double seconds_per_record = pilot.record_seconds / pilot.records;
  const double seconds_per_sample = pilot.sample_seconds / double(pilot.sample_count);
  r.record_seconds = kRecordOverlap * per_px * in.image_pixels * seconds_per_record;
  r.sampling_seconds = spp * in.image_pixels * seconds_per_sample;
  if (!(noise > 0) || !(r.record_seconds > 0) || !(r.sampling_seconds > 0)) return r;

  // error x time minimal at R* = R0 sqrt(N / (I + S) * D / C), with I = kInterpolationFloor N
  // (see header).
  const double interpolation = kInterpolationFloor * noise;
  const double ratio =
      std::sqrt(noise / (interpolation + r.sampling_error) * r.sampling_seconds / r.record_seconds);
  const double lowest = std::max(1.0, std::floor(r0 / 8.0));
  r.record_rays = int(std::lround(std::clamp(r0 * ratio, lowest, double(r0))));
  return r;
}

double TrimmedMean(std::vector<double> values) {
  const size_t k = values.size();
  if (k == 0) return 0;
  std::sort(values.begin(), values.end());
  const size_t kept = k - std::min(k - 1, size_t(std::floor(kTrimmed * double(k))));
  double sum = 0;
  for (size_t i = 0; i < kept; ++i) sum += values[i];
  return sum / double(kept);
}

DenoisedChoice ChooseForDenoising(const BalanceResult& cache, int settings_rays,
                                  const PathPilotFigures& path, double image_pixels,
                                  double min_pixels) {
  DenoisedChoice c;
  c.image_pixels = image_pixels;
  c.min_pixels = min_pixels;
  const double r0 = std::max(1, settings_rays), r = std::max(1, cache.record_rays);
  c.cache_seconds = cache.record_seconds * r / r0 + cache.sampling_seconds;
  c.cache_own = kInterpolationFloor * cache.record_noise + cache.record_noise * r0 / r;
  c.cache_sampling = cache.sampling_error;
  const double path_error_time = path.per_sample_error * path.seconds_per_sample * image_pixels;
  if (!(c.cache_seconds > 0) || !(c.cache_own > 0) || !(path_error_time > 0)) return c;
  c.path = path_error_time / c.cache_seconds;
  c.path_pays =
      image_pixels >= min_pixels && c.path - c.cache_sampling < kDenoiserGain * c.cache_own;
  return c;
}

int PathSppForSeconds(double seconds, const PathPilotFigures& path, double image_pixels, int lo,
                      int hi) {
  const double per_image = path.seconds_per_sample * image_pixels;
  const double spp = per_image > 0 && seconds > 0 ? seconds / per_image : double(lo);
  return int(std::lround(std::clamp(spp, double(lo), double(hi))));
}

}  // namespace irfarm

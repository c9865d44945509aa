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
  std::sort(errors.begin(), errors.end());
  const size_t kept = k - std::min(k - 1, size_t(std::floor(kTrimmed * double(k))));
  for (size_t i = 0; i < kept; ++i) per_sample_error += errors[i];
  noise /= double(k);
  per_px /= double(k);
  per_sample_error /= double(kept);
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

}  // namespace irfarm

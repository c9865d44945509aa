// --target-error's cache refinement (render/renderer.cc): when it gives up on a round.
//
// Each round estimates the cache's error (relMSE by cross-validation at random pixels) and the
// part of it its records' own noise explains; the rest is interpolation error. A round that
// raised only the record rays removes noise (which falls as 1 / rays); one that lowered the
// accuracy a removes interpolation error (about as a^2). The refinement stops, among other
// reasons, when the last round took less than a third off the error: what is left is then
// neither (light leaks through gaps that more rays and records do not close: veach-ajar), and
// going on multiplies the cost for nothing. Except when the error is still more than twice the
// cache's share, the last round raised only the rays, the noise part fell as it should (to at
// most half) and interpolation is now most of what is left: lowering a is the round that removes
// that, and it has not been tried. (Within twice its share, stopping leaves the image within about
// 1.5 E: specular at E = 1e-3 went on from 1.11 E in 8.6 s to 0.76 E in 22.7 s without that limit.)
#pragma once

namespace irfarm {

struct CacheErrorCheck {
  double error = 0;  // the cache's estimated error
  double noise = 0;  // the part of it the records' noise explains (at most `error`)
};

inline bool RefinementStalled(const CacheErrorCheck& previous, const CacheErrorCheck& now,
                              bool last_round_raised_only_rays, double share) {
  const bool interpolation_left = now.error > 2 * share && last_round_raised_only_rays &&
                                  now.noise <= 0.5 * previous.noise &&
                                  now.error - now.noise > now.noise;
  return now.error > (2.0 / 3.0) * previous.error && !interpolation_left;
}

}  // namespace irfarm

// --target-error's cache refinement (render/renderer.cc): when it gives up on a round.
//
// Each round estimates the cache's error (relMSE by cross-validation at random pixels) and the
// part of it its records' own noise explains; the rest is interpolation error. A round that
// raised only the record rays removes noise (which falls as 1 / rays); one that lowered the
// accuracy a removes interpolation error (about as a^2). The refinement stops, among other
// reasons, when the last round took less than a third off the error: what is left is then
// neither (light leaks through gaps that more rays and records do not close: veach-ajar), and
// going on multiplies the cost for nothing. Except when the error is still more than twice the
// cache's share, the last round raised only the rays and the noise part answered them (lost at
// least a third): what kept the error up is then interpolation, and lowering a, the round that
// removes it, has not been tried. (Within twice its share, stopping leaves the image within about
// 1.5 E: specular at E = 1e-3 went on from 1.11 E in 8.6 s to 0.76 E in 22.7 s without that limit.)
// Until 2026-12-04 the noise had to fall to half and interpolation to be most of what was left: a
// room lit by spot lights (bench/make_room.py 401 --lamps bulb, E = 4e-3, seed 7) stopped at
// a = 0.36 after one rays-only round (noise 6.8e-3 -> 4.3e-3 at 3.3x the rays, interpolation
// 2.8e-3) and came out at 1.0e-2, 2.5 E, in 0.7 s, where the defaults take 1.1 s for 1.1e-3.
#pragma once

namespace irfarm {

struct CacheErrorCheck {
  double error = 0;  // the cache's estimated error
  double noise = 0;  // the part of it the records' noise explains (at most `error`)
};

inline bool RefinementStalled(const CacheErrorCheck& previous, const CacheErrorCheck& now,
                              bool last_round_raised_only_rays, double share) {
  const bool interpolation_left = now.error > 2 * share && last_round_raised_only_rays &&
                                  now.noise <= (2.0 / 3.0) * previous.noise;
  return now.error > (2.0 / 3.0) * previous.error && !interpolation_left;
}

}  // namespace irfarm

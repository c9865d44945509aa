// Energy-preserving firefly spreading, the film's last step. A firefly is a pixel whose one
// brightest sample carries more of it than all its other samples together and more than the
// whole value of every neighbouring pixel: a rare path of high weight (light through a chain of
// glass and mirrors, a lamp seen in a sharp reflection from a diffuse bounce) that one pixel
// caught and its neighbours, sampling the same paths as often, did not. That sample's share is
// taken out of the pixel and spread evenly over the (2r+1)^2 pixels around it (itself included,
// clipped to the image): the image keeps its energy, so the estimate stays unbiased over the
// neighbourhood, while the squared error the one sample made falls by the number of pixels it
// is shared among. A small bright feature seen by many samples (a lamp's pixel, a highlight) is
// bright in its other samples or in a neighbour and is left alone.
#pragma once

#include <vector>

#include "render/image.h"

namespace irfarm {

// The radius of the neighbourhood a firefly's share is spread over (5 x 5 pixels).
inline constexpr int kFireflyRadius = 2;
// The fewest samples a pixel must have for its brightest one to be judged: with one sample the
// peak is the whole pixel (every local maximum would pass), with two it is the larger of two.
// Callers give pixels with fewer a zero peak (FireflyPeak).
inline constexpr int kFireflyMinSamples = 8;
inline Vec3 FireflyPeak(const Vec3& peak, int samples) {
  return samples >= kFireflyMinSamples ? peak : Vec3();
}

// Spreads the fireflies of `image`: peak[p] is the contribution of pixel p's brightest sample
// to its value (the sample's weighted radiance over the pixel's weight sum; same size as the
// image; FireflyPeak zeroes it for pixels of too few samples). `layers` (images of the same size
// whose sum is the image, e.g. the direct and indirect AOVs; one of another size is skipped)
// lose and gain the same fraction of each firefly pixel's value per channel, so they still add
// up to the image (the firefly's own split between them is not known: the pixel's is taken).
// Returns how many pixels were spread.
int SpreadFireflies(Image& image, const std::vector<Vec3>& peak,
                    const std::vector<Image*>& layers = {}, int radius = kFireflyRadius);

}  // namespace irfarm

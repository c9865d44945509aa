#include "render/firefly_filter.h"

#include <algorithm>

namespace irfarm {

int SpreadFireflies(Image& image, const std::vector<Vec3>& peak, const std::vector<Image*>& layers,
                    int radius) {
  const int w = image.width, h = image.height;
  if (peak.size() != image.pixels.size() || w == 0 || h == 0) return 0;
  // The peak as the pixel can hold it: per channel within [0, its value] (colour the pixel does
  // not have, e.g. from other samples of another colour, is not the firefly's).
  const auto held = [&](size_t p) {
    Vec3 c;
    for (int k = 0; k < 3; ++k)
      c[k] = std::clamp(peak[p][k], 0.0f, std::max(0.0f, image.pixels[p][k]));
    return c;
  };
  // Decide on the image as rendered (a spread share must not make a neighbour look dark or
  // bright to the test), then move the shares.
  std::vector<int> fireflies;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t p = size_t(y) * w + x;
      const float c = Luminance(held(p));
      const float v = Luminance(image.pixels[p]);
      if (!(c > 0) || !(c > v - c)) continue;  // the other samples together carry as much
      bool above = true;
      for (int dy = -1; dy <= 1 && above; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if ((dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
          if (!(c > Luminance(image.at(xx, yy)))) {
            above = false;
            break;
          }
        }
      if (above) fireflies.push_back(int(p));
    }
  for (const int p : fireflies) {
    const int x = p % w, y = p / w;
    // The share as a fraction of the pixel's value per channel; the layers move the same
    // fraction of theirs.
    const Vec3 share = held(size_t(p));
    Vec3 fraction;
    for (int k = 0; k < 3; ++k) {
      const float v = image.pixels[size_t(p)][k];
      fraction[k] = v > 0 ? share[k] / v : 0.0f;
    }
    const int x0 = std::max(0, x - radius), x1 = std::min(w - 1, x + radius);
    const int y0 = std::max(0, y - radius), y1 = std::min(h - 1, y + radius);
    const float n = float((x1 - x0 + 1) * (y1 - y0 + 1));
    const auto move = [&](Image& im) {
      const Vec3 share = im.pixels[size_t(p)] * fraction;
      const Vec3 each = share / n;
      im.pixels[size_t(p)] -= share;
      for (int yy = y0; yy <= y1; ++yy)
        for (int xx = x0; xx <= x1; ++xx) im.at(xx, yy) += each;
    };
    move(image);
    for (Image* layer : layers)
      if (layer->pixels.size() == image.pixels.size()) move(*layer);
  }
  return int(fireflies.size());
}

}  // namespace irfarm

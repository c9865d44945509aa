// A guide table for sampling a discrete distribution by its cumulative sums: the first entry of
// a non-decreasing array above u * total (what std::upper_bound finds), in expected constant time
// (Chen and Asau's cutpoint method). Each of K buckets of u keeps the first entry any u in it can
// land on; a short forward scan from there finds the answer. The answer is the binary search's,
// entry for entry (the bucket's start is taken a little below the bucket's lowest value, so
// rounding cannot put it past the answer).
//
// A binary search over a large table (an environment's sun: 10,240 sub-cells) mispredicts a
// branch at half of its steps and misses the cache at the deep ones; the guide reads one bucket
// and, on average, about two entries (with K = n buckets, a bucket spans n / K entries plus the
// one it starts in, weighed by the buckets' probabilities).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace irfarm {

class CdfGuide {
 public:
  // `cdf`: n non-decreasing cumulative sums (the last one the total, > 0); `buckets` > 0.
  void Build(const std::vector<float>& cdf, size_t buckets) {
    start_.clear();
    if (cdf.empty() || buckets == 0) return;
    const double total = double(cdf.back());
    start_.resize(buckets);
    for (size_t b = 0; b < buckets; ++b) {
      // Below every u * total of bucket b (u >= b / K up to float rounding): the margin of 1e-5
      // is far above the float products' relative error (1.2e-7).
      const float low = float(total * double(b) / double(buckets) * (1 - 1e-5));
      start_[b] = uint32_t(std::upper_bound(cdf.begin(), cdf.end(), low) - cdf.begin());
    }
  }
  bool empty() const { return start_.empty(); }

  // The first k with cdf[k] > x (cdf.size() if none), for x = u * cdf.back() and u in [0, 1):
  // std::upper_bound(cdf.begin(), cdf.end(), x) - cdf.begin().
  size_t UpperBound(const std::vector<float>& cdf, float u, float x) const {
    const size_t buckets = start_.size();
    const size_t b = std::min(buckets - 1, size_t(std::max(0.0f, u) * float(buckets)));
    size_t k = start_[b];
    const size_t n = cdf.size();
    while (k < n && cdf[k] <= x) ++k;
    return k;
  }

 private:
  std::vector<uint32_t> start_;
};

}  // namespace irfarm

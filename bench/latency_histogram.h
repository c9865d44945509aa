// LatencyHistogram: microsecond latencies in log-linear buckets (64 per power of two, so a
// percentile is read to within 1/64 = 1.6% of its value), from 0 to 2^32 us. Adding is an index
// computation and an increment (the scale simulation adds one per received record); histograms of
// several threads are summed with Merge before reading percentiles. Not thread-safe.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

namespace irfarm {

class LatencyHistogram {
 public:
  LatencyHistogram() : counts_(kBuckets, 0) {}

  void Add(uint32_t us) {
    ++counts_[Bucket(us)];
    ++count_;
  }
  void Merge(const LatencyHistogram& o) {
    for (size_t i = 0; i < kBuckets; ++i) counts_[i] += o.counts_[i];
    count_ += o.count_;
  }
  uint64_t count() const { return count_; }
  // The q-quantile (0 <= q <= 1) in milliseconds: the middle of the bucket holding it; 0 when
  // empty.
  double QuantileMs(double q) const {
    if (count_ == 0) return 0;
    const uint64_t rank = std::min<uint64_t>(count_ - 1, uint64_t(q * double(count_)));
    uint64_t seen = 0;
    for (size_t i = 0; i < kBuckets; ++i) {
      seen += counts_[i];
      if (seen > rank) return 0.5 * (Lower(i) + Lower(i + 1)) / 1000.0;
    }
    return Lower(kBuckets) / 1000.0;
  }

 private:
  // Values below 64 us get a bucket each; above, 64 buckets per power of two.
  static constexpr size_t kBuckets = 64 + 26 * 64;
  static size_t Bucket(uint32_t us) {
    if (us < 64) return us;
    const int e = 31 - __builtin_clz(us);  // 6..31
    return size_t(64 + (e - 6) * 64 + int((us >> (e - 6)) - 64));
  }
  static double Lower(size_t b) {
    if (b < 64) return double(b);
    const size_t e = (b - 64) / 64 + 6, m = (b - 64) % 64 + 64;
    return double(m) * double(uint64_t(1) << (e - 6));
  }
  std::vector<uint64_t> counts_;
  uint64_t count_ = 0;
};

}  // namespace irfarm

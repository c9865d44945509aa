// A tile counter on stderr for a render's passes ("overture: tiles 12/40  3.1 tiles/s  ETA 9s"),
// rewritten in place at most every 0.2 s; Tick() may be called from any thread. Disabled (quiet
// renders, the worker), it only counts.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>

namespace irfarm {

class Progress {
 public:
  Progress(bool enabled, int total, const char* what)
      : enabled_(enabled), total_(total), what_(what), start_(Now()) {}
  ~Progress() {
    if (enabled_) std::fprintf(stderr, "\n");
  }
  void Tick() {
    const int done = ++done_;
    if (!enabled_) return;
    const double now = Now();
    double last = last_.load();
    if (done < total_ && now - last < 0.2) return;
    if (!last_.compare_exchange_strong(last, now)) return;
    const double el = now - start_, rate = done / std::max(el, 1e-9);
    std::fprintf(stderr, "\r%s: tiles %d/%d  %.1f tiles/s  ETA %.0fs   ", what_, done, total_, rate,
                 (total_ - done) / std::max(rate, 1e-9));
    std::fflush(stderr);
  }

 private:
  static double Now() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
  bool enabled_;
  int total_;
  const char* what_;
  double start_;
  std::atomic<int> done_{0};
  std::atomic<double> last_{0};
};

}  // namespace irfarm

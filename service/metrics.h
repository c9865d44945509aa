// Metrics: counters, gauges and histograms that the coordinator and the worker export in the
// Prometheus text exposition format (version 0.0.4) on `--metrics ADDR` (service/http_server.h).
// prometheus-cpp is not a Debian 12 package, and the text format is small, so it is written here.
//
// A MetricsRegistry owns its metrics (no global registry: each process makes one and hands
// pointers to what updates them). Add* is called at start-up and returns a pointer that stays
// valid for the registry's life; updates are lock-free atomics and allocate nothing, so they may
// sit on hot paths. Values known only at scrape time (jobs by state, resident memory) come from
// collectors: functions called on each Render() that write whole metric families.
//
// Names follow Prometheus conventions: counters end in _total, units are base units (seconds,
// bytes). Label values are escaped (\\, \", \n) when rendered.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "service/http_server.h"

namespace irfarm {

using MetricLabels = std::vector<std::pair<std::string, std::string>>;

// A monotonically increasing count (events, bytes).
class Counter {
 public:
  void Add(uint64_t n = 1) { value_.fetch_add(n, std::memory_order_relaxed); }
  uint64_t value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<uint64_t> value_{0};
};

// A value that goes up and down.
class Gauge {
 public:
  void Set(double v) { value_.store(v, std::memory_order_relaxed); }
  void Add(double d);
  double value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<double> value_{0};
};

// Observations counted into fixed buckets (upper bounds, ascending; +Inf is implicit), with
// their count and sum: latencies in seconds.
class Histogram {
 public:
  explicit Histogram(std::vector<double> bounds);
  void Observe(double v);
  const std::vector<double>& bounds() const { return bounds_; }
  // Non-cumulative count of bucket i (i == bounds().size(): above the last bound).
  uint64_t bucket(size_t i) const { return counts_[i].load(std::memory_order_relaxed); }
  uint64_t count() const { return count_.load(std::memory_order_relaxed); }
  double sum() const { return sum_.load(std::memory_order_relaxed); }

 private:
  const std::vector<double> bounds_;
  std::unique_ptr<std::atomic<uint64_t>[]> counts_;  // bounds_.size() + 1
  std::atomic<uint64_t> count_{0};
  std::atomic<double> sum_{0};
};

// Observes the seconds from its construction to its destruction into a histogram (null: none).
class ScopedTimer {
 public:
  explicit ScopedTimer(Histogram* h) : h_(h), start_(std::chrono::steady_clock::now()) {}
  ~ScopedTimer() {
    if (h_)
      h_->Observe(std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
  }
  ScopedTimer(const ScopedTimer&) = delete;
  ScopedTimer& operator=(const ScopedTimer&) = delete;

 private:
  Histogram* h_;
  std::chrono::steady_clock::time_point start_;
};

// Latency buckets from 100 us to 10 s (RPCs, store calls, tiles), in seconds.
std::vector<double> LatencyBuckets();

// Writes whole metric families in the text format; what collectors are handed.
class MetricsWriter {
 public:
  explicit MetricsWriter(std::string* out) : out_(out) {}
  // Starts a family: "# HELP" and "# TYPE" lines. type: "counter", "gauge" or "histogram".
  void Family(const std::string& name, const std::string& type, const std::string& help);
  // One sample line of the current family (name may carry a suffix such as _bucket).
  void Sample(const std::string& name, const MetricLabels& labels, double value);

 private:
  std::string* out_;
};

class MetricsRegistry {
 public:
  // Metrics of one name may be added several times with different labels (one family); help
  // and type come from the first. The pointers stay valid for the registry's life.
  Counter* AddCounter(const std::string& name, const std::string& help,
                      const MetricLabels& labels = {});
  Gauge* AddGauge(const std::string& name, const std::string& help,
                  const MetricLabels& labels = {});
  Histogram* AddHistogram(const std::string& name, const std::string& help,
                          std::vector<double> bounds, const MetricLabels& labels = {});
  // Called on every Render(), after the registered metrics; writes its own families (names
  // distinct from the registered ones). Returns a handle for RemoveCollector.
  uint64_t AddCollector(std::function<void(MetricsWriter&)> collect);
  // Removes a collector (its owner is going away): no Render() calls it after this returns.
  void RemoveCollector(uint64_t handle);

  // The text exposition of every metric, families in the order they were first added.
  std::string Render() const;

 private:
  struct Child {
    MetricLabels labels;
    std::unique_ptr<Counter> counter;
    std::unique_ptr<Gauge> gauge;
    std::unique_ptr<Histogram> histogram;
  };
  struct Family {
    std::string name, type, help;
    std::vector<Child> children;
  };
  Family& FamilyFor(const std::string& name, const std::string& type, const std::string& help);

  mutable std::mutex mu_;  // guards the structure (Add*, Render), not the values
  std::vector<std::unique_ptr<Family>> families_;
  std::vector<std::pair<uint64_t, std::function<void(MetricsWriter&)>>> collectors_;
  uint64_t next_collector_ = 1;
};

// Serves `metrics` (not owned, must outlive the server) as Prometheus text at GET /metrics on
// HOST:PORT: what --metrics starts in the coordinator and the worker.
absl::StatusOr<std::unique_ptr<HttpServer>> ServeMetrics(const std::string& address,
                                                         const MetricsRegistry* metrics);

// What `--metrics ADDR` does in irfarm-coordinator and irfarm-worker: nothing (nullptr) when
// `address` is empty (the flag's default, metrics off), else ServeMetrics and an info log line
// with the URL. The error names the flag ("--metrics: ..."), for the binaries to print and exit.
absl::StatusOr<std::unique_ptr<HttpServer>> StartMetricsServer(const std::string& address,
                                                               const MetricsRegistry* metrics);

// The process's resident memory and CPU time (process_resident_memory_bytes,
// process_cpu_seconds_total), read from /proc and getrusage at scrape time.
void AddProcessMetrics(MetricsRegistry* registry);

}  // namespace irfarm

// Metrics registry and the Prometheus text format (see metrics.h).
#include "service/metrics.h"

#include <algorithm>

#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>

namespace irfarm {
namespace {

// Prometheus text numbers: integers exactly, others with full precision, +Inf/-Inf/NaN spelled
// the way the format wants them.
std::string FormatValue(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  char buf[40];
  if (v == std::floor(v) && std::fabs(v) < 9e15) {
    std::snprintf(buf, sizeof buf, "%.0f", v);
    return buf;
  }
  // The shortest of 15..17 significant digits that reads back as the same double.
  for (int digits = 15; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

void AppendEscaped(const std::string& s, bool help, std::string* out) {
  for (char c : s) {
    if (c == '\\') {
      *out += "\\\\";
    } else if (c == '\n') {
      *out += "\\n";
    } else if (c == '"' && !help) {
      *out += "\\\"";
    } else {
      *out += c;
    }
  }
}

void AtomicAdd(std::atomic<double>* a, double d) {
  double old = a->load(std::memory_order_relaxed);
  while (!a->compare_exchange_weak(old, old + d, std::memory_order_relaxed)) {
  }
}

}  // namespace

void Gauge::Add(double d) { AtomicAdd(&value_, d); }

Histogram::Histogram(std::vector<double> bounds)
    : bounds_(std::move(bounds)), counts_(new std::atomic<uint64_t>[bounds_.size() + 1]) {
  for (size_t i = 0; i <= bounds_.size(); ++i) counts_[i] = 0;
}

void Histogram::Observe(double v) {
  size_t i = 0;
  while (i < bounds_.size() && v > bounds_[i]) ++i;  // le: v <= bound counts in that bucket
  counts_[i].fetch_add(1, std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_relaxed);
  AtomicAdd(&sum_, v);
}

std::vector<double> LatencyBuckets() {
  return {0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025,
          0.05,   0.1,     0.25,   0.5,   1,      2.5,   5,    10};
}

void MetricsWriter::Family(const std::string& name, const std::string& type,
                           const std::string& help) {
  *out_ += "# HELP " + name + " ";
  AppendEscaped(help, true, out_);
  *out_ += "\n# TYPE " + name + " " + type + "\n";
}

void MetricsWriter::Sample(const std::string& name, const MetricLabels& labels, double value) {
  *out_ += name;
  if (!labels.empty()) {
    *out_ += '{';
    for (size_t i = 0; i < labels.size(); ++i) {
      if (i) *out_ += ',';
      *out_ += labels[i].first + "=\"";
      AppendEscaped(labels[i].second, false, out_);
      *out_ += '"';
    }
    *out_ += '}';
  }
  *out_ += ' ' + FormatValue(value) + '\n';
}

MetricsRegistry::Family& MetricsRegistry::FamilyFor(const std::string& name,
                                                    const std::string& type,
                                                    const std::string& help) {
  for (auto& f : families_)
    if (f->name == name) return *f;
  families_.push_back(std::make_unique<Family>(Family{name, type, help, {}}));
  return *families_.back();
}

Counter* MetricsRegistry::AddCounter(const std::string& name, const std::string& help,
                                     const MetricLabels& labels) {
  std::lock_guard<std::mutex> lock(mu_);
  Family& f = FamilyFor(name, "counter", help);
  f.children.push_back(Child{labels, std::make_unique<Counter>(), nullptr, nullptr});
  return f.children.back().counter.get();
}

Gauge* MetricsRegistry::AddGauge(const std::string& name, const std::string& help,
                                 const MetricLabels& labels) {
  std::lock_guard<std::mutex> lock(mu_);
  Family& f = FamilyFor(name, "gauge", help);
  f.children.push_back(Child{labels, nullptr, std::make_unique<Gauge>(), nullptr});
  return f.children.back().gauge.get();
}

Histogram* MetricsRegistry::AddHistogram(const std::string& name, const std::string& help,
                                         std::vector<double> bounds, const MetricLabels& labels) {
  std::lock_guard<std::mutex> lock(mu_);
  Family& f = FamilyFor(name, "histogram", help);
  f.children.push_back(
      Child{labels, nullptr, nullptr, std::make_unique<Histogram>(std::move(bounds))});
  return f.children.back().histogram.get();
}

uint64_t MetricsRegistry::AddCollector(std::function<void(MetricsWriter&)> collect) {
  std::lock_guard<std::mutex> lock(mu_);
  collectors_.emplace_back(next_collector_, std::move(collect));
  return next_collector_++;
}

void MetricsRegistry::RemoveCollector(uint64_t handle) {
  std::lock_guard<std::mutex> lock(mu_);  // waits for a Render() in progress
  collectors_.erase(std::remove_if(collectors_.begin(), collectors_.end(),
                                   [&](const auto& c) { return c.first == handle; }),
                    collectors_.end());
}

std::string MetricsRegistry::Render() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::string out;
  MetricsWriter w(&out);
  for (const auto& f : families_) {
    w.Family(f->name, f->type, f->help);
    for (const Child& c : f->children) {
      if (c.counter) {
        w.Sample(f->name, c.labels, double(c.counter->value()));
      } else if (c.gauge) {
        w.Sample(f->name, c.labels, c.gauge->value());
      } else {
        const Histogram& h = *c.histogram;
        MetricLabels labels = c.labels;
        labels.emplace_back("le", "");
        uint64_t cumulative = 0;
        for (size_t i = 0; i <= h.bounds().size(); ++i) {
          cumulative += h.bucket(i);
          labels.back().second = i < h.bounds().size() ? FormatValue(h.bounds()[i]) : "+Inf";
          w.Sample(f->name + "_bucket", labels, double(cumulative));
        }
        w.Sample(f->name + "_sum", c.labels, h.sum());
        w.Sample(f->name + "_count", c.labels, double(cumulative));
      }
    }
  }
  for (const auto& [handle, collect] : collectors_) collect(w);
  return out;
}

void AddProcessMetrics(MetricsRegistry* registry) {
  registry->AddCollector([](MetricsWriter& w) {
    // /proc/self/statm: total and resident size in pages.
    long pages = 0, resident = 0;
    std::ifstream statm("/proc/self/statm");
    if (statm >> pages >> resident) {
      w.Family("process_resident_memory_bytes", "gauge", "Resident memory size in bytes.");
      w.Sample("process_resident_memory_bytes", {},
               double(resident) * double(sysconf(_SC_PAGESIZE)));
    }
    rusage u{};
    if (getrusage(RUSAGE_SELF, &u) == 0) {
      const double cpu = double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
                         1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
      w.Family("process_cpu_seconds_total", "counter", "User and system CPU time in seconds.");
      w.Sample("process_cpu_seconds_total", {}, cpu);
    }
  });
}

absl::StatusOr<std::unique_ptr<HttpServer>> ServeMetrics(const std::string& address,
                                                         const MetricsRegistry* metrics) {
  return HttpServer::Start(
      address,
      {{"GET", "/metrics", [metrics](const HttpRequest&) {
          return HttpResponse{200, "text/plain; version=0.0.4; charset=utf-8", metrics->Render()};
        }}});
}

absl::StatusOr<std::unique_ptr<HttpServer>> StartMetricsServer(const std::string& address,
                                                               const MetricsRegistry* metrics) {
  if (address.empty()) return nullptr;
  absl::StatusOr<std::unique_ptr<HttpServer>> server = ServeMetrics(address, metrics);
  if (!server.ok()) {
    return absl::Status(server.status().code(),
                        "--metrics: " + std::string(server.status().message()));
  }
  spdlog::info("metrics on http://{}/metrics", address);
  return server;
}

}  // namespace irfarm

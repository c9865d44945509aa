// MetricsRegistry's text format (service/metrics.h): the exact lines Prometheus' text format
// 0.0.4 specifies for counters with escaped label values, cumulative histogram buckets with +Inf,
// _sum and _count, and collectors. (tests/service/metrics_test.sh parses real scrapes with the
// Prometheus client's own parser.)
#include <gtest/gtest.h>

#include "service/metrics.h"

namespace irfarm {
namespace {

TEST(MetricsFormatTest, CounterWithEscapedLabels) {
  MetricsRegistry r;
  Counter* c = r.AddCounter("x_total", "Help with \\ and\nnewline.", {{"job", "a\"b\\c\nd"}});
  c->Add(3);
  c->Add();
  EXPECT_EQ(r.Render(),
            "# HELP x_total Help with \\\\ and\\nnewline.\n"
            "# TYPE x_total counter\n"
            "x_total{job=\"a\\\"b\\\\c\\nd\"} 4\n");
}

TEST(MetricsFormatTest, HistogramBucketsAreCumulative) {
  MetricsRegistry r;
  Histogram* h = r.AddHistogram("lat_seconds", "Latency.", {0.1, 1}, {{"op", "get"}});
  h->Observe(0.05);
  h->Observe(0.1);  // le="0.1" includes 0.1 itself
  h->Observe(0.5);
  h->Observe(7);
  EXPECT_EQ(r.Render(),
            "# HELP lat_seconds Latency.\n"
            "# TYPE lat_seconds histogram\n"
            "lat_seconds_bucket{op=\"get\",le=\"0.1\"} 2\n"
            "lat_seconds_bucket{op=\"get\",le=\"1\"} 3\n"
            "lat_seconds_bucket{op=\"get\",le=\"+Inf\"} 4\n"
            "lat_seconds_sum{op=\"get\"} 7.65\n"
            "lat_seconds_count{op=\"get\"} 4\n");
}

TEST(MetricsFormatTest, FamiliesGroupChildrenAndCollectorsFollow) {
  MetricsRegistry r;
  r.AddCounter("a_total", "A.", {{"k", "1"}})->Add(1);
  r.AddGauge("g", "G.")->Set(0.25);
  r.AddCounter("a_total", "", {{"k", "2"}})->Add(2);
  r.AddCollector([](MetricsWriter& w) {
    w.Family("c", "gauge", "C.");
    w.Sample("c", {}, 1.5);
  });
  EXPECT_EQ(r.Render(),
            "# HELP a_total A.\n# TYPE a_total counter\n"
            "a_total{k=\"1\"} 1\na_total{k=\"2\"} 2\n"
            "# HELP g G.\n# TYPE g gauge\ng 0.25\n"
            "# HELP c C.\n# TYPE c gauge\nc 1.5\n");
}

// A collector's owner may go before the registry (a coordinator whose JobManager failed to start
// while its metrics server was up): once removed, Render() no longer calls it.
TEST(MetricsFormatTest, ARemovedCollectorIsNotCalled) {
  MetricsRegistry r;
  int calls = 0;
  const uint64_t a = r.AddCollector([&](MetricsWriter& w) {
    ++calls;
    w.Family("a", "gauge", "A.");
    w.Sample("a", {}, 1);
  });
  r.AddCollector([](MetricsWriter& w) {
    w.Family("b", "gauge", "B.");
    w.Sample("b", {}, 2);
  });
  EXPECT_NE(r.Render().find("a 1"), std::string::npos);
  r.RemoveCollector(a);
  const std::string after = r.Render();
  EXPECT_EQ(after.find("a 1"), std::string::npos);
  EXPECT_NE(after.find("b 2"), std::string::npos);
  EXPECT_EQ(calls, 1);
}

}  // namespace
}  // namespace irfarm

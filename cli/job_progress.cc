// Job progress, rate and ETA (see job_progress.h).
#include "cli/job_progress.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace irfarm {
namespace {

bool IsFinal(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
}

}  // namespace

JobProgress ProgressOf(const v1::Job& job) {
  JobProgress p;
  const int total = std::max(1, job.tiles_total());
  p.fraction = std::clamp(double(job.tiles_done()) / total, 0.0, 1.0);
  if (job.tiles_done() > 0 && job.elapsed_seconds() > 0) {
    p.tiles_per_second = job.tiles_done() / job.elapsed_seconds();
    p.eta_seconds = double(std::max(0, job.tiles_total() - job.tiles_done())) / p.tiles_per_second;
  }
  return p;
}

std::string FormatDuration(double seconds) {
  if (!(seconds >= 0) || !std::isfinite(seconds)) return "?";
  char buf[32];
  const long s = std::lround(seconds);
  if (s < 60) {
    std::snprintf(buf, sizeof buf, "%lds", s);
  } else if (s < 3600) {
    std::snprintf(buf, sizeof buf, "%ldm%02lds", s / 60, s % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%ldh%02ldm", s / 3600, (s % 3600) / 60);
  }
  return buf;
}

std::string StateName(v1::JobState state) {
  const std::string n = v1::JobState_Name(state);
  const std::string prefix = "JOB_STATE_";
  if (n.compare(0, prefix.size(), prefix) != 0) return "STATE_" + std::to_string(int(state));
  return n.substr(prefix.size());
}

std::string ProgressLine(const v1::Job& job, int bar_width) {
  const JobProgress p = ProgressOf(job);
  const int filled = std::clamp(int(p.fraction * bar_width), 0, bar_width);
  const std::string state = StateName(job.state());
  std::string timing;
  if (IsFinal(job.state())) {
    if (job.elapsed_seconds() > 0) timing = "took " + FormatDuration(job.elapsed_seconds());
  } else if (p.eta_seconds >= 0) {
    char rate[32];
    std::snprintf(rate, sizeof rate, "%.2f tiles/s", p.tiles_per_second);
    timing = std::string(rate) + "  ETA " + FormatDuration(p.eta_seconds);
  } else {
    timing = "ETA ?";
  }
  char line[512];
  std::snprintf(line, sizeof line, "%-10s %-9s [%s%s] %3d%%  %d/%d tiles  %s  records %llu",
                job.id().c_str(), state.c_str(), std::string(size_t(filled), '#').c_str(),
                std::string(size_t(bar_width - filled), '.').c_str(),
                int(std::floor(p.fraction * 100)), job.tiles_done(), job.tiles_total(),
                timing.c_str(), static_cast<unsigned long long>(job.records_merged()));
  return line;
}

}  // namespace irfarm

#include "render/render_stats.h"

#include <ctime>

#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace irfarm {
namespace {

double WallNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string Quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string Num(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

}  // namespace

double ProcessCpuSeconds() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
         1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

double PeakRssMiB() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

PhaseTimer::PhaseTimer(std::string name)
    : name_(std::move(name)), wall0_(WallNow()), cpu0_(ProcessCpuSeconds()) {}

PhaseTime PhaseTimer::Stop() const {
  return PhaseTime{name_, WallNow() - wall0_, ProcessCpuSeconds() - cpu0_};
}

double RenderStats::PhaseWall(const std::string& name) const {
  for (const PhaseTime& p : phases)
    if (p.name == name) return p.wall_seconds;
  return 0;
}

std::string RenderStats::ToJson() const {
  const RenderCounters& c = counters;
  std::ostringstream o;
  double wall = 0, cpu = 0;
  o << "{\n  \"scene\": " << Quote(scene) << ",\n  \"integrator\": " << Quote(integrator)
    << ",\n  \"width\": " << width << ", \"height\": " << height << ", \"spp\": " << spp
    << ", \"threads\": " << threads << ", \"seed\": " << seed << ",\n";
  o << "  \"settings\": {\"accuracy\": " << Num(accuracy) << ", \"record_rays\": " << record_rays
    << ", \"strata\": [" << strata_theta << ", " << strata_phi
    << "], \"light_samples\": " << light_samples << ", \"cache_levels\": " << cache_levels
    << ", \"min_spacing_px\": " << Num(min_spacing_px)
    << ", \"max_spacing_px\": " << Num(max_spacing_px) << "},\n";
  o << "  \"seconds\": {";
  for (size_t i = 0; i < phases.size(); ++i) {
    o << (i ? ", " : "") << Quote(phases[i].name) << ": " << Num(phases[i].wall_seconds);
    wall += phases[i].wall_seconds;
  }
  o << (phases.empty() ? "" : ", ") << "\"total\": " << Num(wall) << "},\n";
  o << "  \"cpu_seconds\": {";
  for (size_t i = 0; i < phases.size(); ++i) {
    o << (i ? ", " : "") << Quote(phases[i].name) << ": " << Num(phases[i].cpu_seconds);
    cpu += phases[i].cpu_seconds;
  }
  o << (phases.empty() ? "" : ", ") << "\"total\": " << Num(cpu) << "},\n";
  const uint64_t total_rays = c.camera_rays + c.bounce_rays + c.shadow_rays + c.record_rays;
  o << "  \"rays\": {\"camera\": " << c.camera_rays << ", \"bounce\": " << c.bounce_rays
    << ", \"shadow\": " << c.shadow_rays << ", \"record\": " << c.record_rays
    << ", \"total\": " << total_rays
    << ", \"shadow_skipped_unreachable_light\": " << c.lights_skipped << "},\n";
  o << "  \"records\": {\"computed\": " << c.records_computed
    << ", \"computed_secondary\": " << c.records_secondary
    << ", \"computed_hessian\": " << c.records_hessian
    << ", \"computed_overture\": " << records_overture << ", \"received\": " << records_received
    << ", \"in_cache\": " << records_in_cache << ", \"used\": " << c.records_used
    << ", \"used_remote\": " << c.remote_records_used
    << ", \"compute_thread_seconds\": " << Num(c.record_seconds) << "},\n";
  o << "  \"cache\": {\"lookups\": " << c.lookups << ", \"hits\": " << c.lookup_hits
    << ", \"region_lookups\": " << c.region_lookups
    << ", \"hit_rate\": " << Num(c.lookups ? double(c.lookup_hits) / double(c.lookups) : 0)
    << ", \"records_per_hit\": "
    << Num(c.lookup_hits ? double(c.records_used) / double(c.lookup_hits) : 0)
    << ", \"glossy_bounces\": " << c.glossy_bounces << "},\n";
  o << "  \"caustics\": {\"photons\": " << caustic_photons
    << ", \"emitted\": " << caustic_photons_emitted << "},\n";
  o << "  \"sampling\": {\"spp_min\": " << spp_min << ", \"spp_mean\": " << Num(spp_mean)
    << ", \"spp_max\": " << spp_max << ", \"pixels_stopped_early\": " << pixels_stopped_early
    << ", \"adaptive_rounds\": " << adaptive_rounds
    << ", \"nonfinite_samples\": " << c.nonfinite_samples << "},\n";
  o << "  \"error_estimate\": {\"relmse\": "
    << Num(estimated_sampling_relmse + std::max(0.0, estimated_cache_relmse))
    << ", \"sampling_relmse\": " << Num(estimated_sampling_relmse)
    << ", \"cache_relmse\": " << Num(estimated_cache_relmse)
    << ", \"target_error\": " << Num(target_error) << "},\n";
  if (balanced)
    o << "  \"record_balance\": {\"record_rays\": " << balance.record_rays
      << ", \"record_noise_relmse\": " << Num(balance.record_noise)
      << ", \"sampling_relmse\": " << Num(balance.sampling_error)
      << ", \"expected_spp\": " << Num(balance.expected_spp)
      << ", \"record_thread_seconds\": " << Num(balance.record_seconds)
      << ", \"sampling_thread_seconds\": " << Num(balance.sampling_seconds)
      << ", \"pilot_records\": " << balance.pilot_records
      << ", \"cache_levels\": " << balance.cache_levels
      << ", \"one_level_record_noise_relmse\": " << Num(balance.one_level_record_noise)
      << ", \"one_level_sampling_relmse\": " << Num(balance.one_level_sampling_error) << "},\n";
  o << "  \"tiles\": {\"count\": " << tiles << ", \"size\": " << tile_size << "},\n";
  o << "  \"geometry\": {\"triangles\": " << triangles
    << ", \"degenerate_dropped\": " << degenerate_dropped << "},\n";
  o << "  \"image\": {\"mean_rgb\": [" << Num(mean_rgb.x) << ", " << Num(mean_rgb.y) << ", "
    << Num(mean_rgb.z) << "], \"nonfinite_pixels\": " << nonfinite_pixels << "},\n";
  o << "  \"peak_rss_mib\": " << Num(PeakRssMiB()) << ",\n";
  o << "  \"warnings\": [";
  for (size_t i = 0; i < warnings.size(); ++i) o << (i ? ", " : "") << Quote(warnings[i]);
  o << "]\n}\n";
  return o.str();
}

absl::Status WriteTextFile(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary);
    if (!f) return absl::InternalError(path + ": cannot open for writing");
    f << text;
    if (!f) return absl::InternalError(path + ": write failed");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    return absl::InternalError(path + ": cannot rename into place");
  return absl::OkStatus();
}

}  // namespace irfarm

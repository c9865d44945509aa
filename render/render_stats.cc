#include "render/render_stats.h"

#include <ctime>

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include <nlohmann/json.hpp>

namespace irfarm {
namespace {

double WallNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// The stats file (--stats): key order kept as written. Non-finite numbers (none expected) are
// written as null.
using Json = nlohmann::ordered_json;

// A float as the double of its shortest decimal that reads back as the same float, so that the
// file says 0.1 for 0.1f, not 0.10000000149011612.
double Short(float v) {
  if (!std::isfinite(v)) return v;
  char buf[32];
  for (int digits = 6; digits < 9; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, double(v));
    if (std::strtof(buf, nullptr) == v) return std::strtod(buf, nullptr);
  }
  std::snprintf(buf, sizeof buf, "%.9g", double(v));
  return std::strtod(buf, nullptr);
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
  Json j;
  j["scene"] = scene;
  j["integrator"] = integrator;
  j["width"] = width;
  j["height"] = height;
  j["spp"] = spp;
  j["threads"] = threads;
  j["seed"] = seed;
  j["settings"] = {{"accuracy", Short(accuracy)},
                   {"record_rays", record_rays},
                   {"strata", {strata_theta, strata_phi}},
                   {"light_samples", light_samples},
                   {"cache_levels", cache_levels},
                   {"min_spacing_px", Short(min_spacing_px)},
                   {"max_spacing_px", Short(max_spacing_px)},
                   {"lookup_factor", Short(lookup_factor)},
                   {"spacing", spacing},
                   {"interpolation", interpolation}};
  Json& seconds = j["seconds"] = Json::object();
  Json& cpu_seconds = j["cpu_seconds"] = Json::object();
  double wall = 0, cpu = 0;
  for (const PhaseTime& p : phases) {
    seconds[p.name] = p.wall_seconds;
    cpu_seconds[p.name] = p.cpu_seconds;
    wall += p.wall_seconds;
    cpu += p.cpu_seconds;
  }
  seconds["total"] = wall;
  cpu_seconds["total"] = cpu;
  j["rays"] = {{"camera", c.camera_rays},
               {"bounce", c.bounce_rays},
               {"shadow", c.shadow_rays},
               {"record", c.record_rays},
               {"total", c.camera_rays + c.bounce_rays + c.shadow_rays + c.record_rays},
               {"shadow_skipped_unreachable_light", c.lights_skipped}};
  j["records"] = {{"computed", c.records_computed},
                  {"computed_secondary", c.records_secondary},
                  {"computed_secondary_heavy", c.records_secondary_heavy},
                  {"computed_hessian", c.records_hessian},
                  {"computed_overture", records_overture},
                  {"received", records_received},
                  {"in_cache", records_in_cache},
                  {"used", c.records_used},
                  {"used_remote", c.remote_records_used},
                  {"compute_thread_seconds", c.record_seconds}};
  j["cache"] = {
      {"lookups", c.lookups},
      {"hits", c.lookup_hits},
      {"region_lookups", c.region_lookups},
      {"hit_rate", c.lookups ? double(c.lookup_hits) / double(c.lookups) : 0.0},
      {"records_per_hit", c.lookup_hits ? double(c.records_used) / double(c.lookup_hits) : 0.0},
      {"glossy_bounces", c.glossy_bounces}};
  j["caustics"] = {{"photons", caustic_photons}, {"emitted", caustic_photons_emitted}};
  j["sampling"] = {{"spp_min", spp_min},
                   {"spp_mean", spp_mean},
                   {"spp_max", spp_max},
                   {"pixels_stopped_early", pixels_stopped_early},
                   {"adaptive_rounds", adaptive_rounds},
                   {"fireflies_spread", fireflies_spread},
                   {"nonfinite_samples", c.nonfinite_samples}};
  // The whole image's estimate only where every part of it was estimated: an irrcache render
  // outside --target-error does not cross-validate its records (cache_relmse -1), and its camera
  // samples' part alone was 5-10x below the measured error on rooms (room-a 5.6e-5 against about
  // 3e-4 less the reference's own), so the total is null there, not that part.
  const bool cache_unknown = integrator == "irrcache" && estimated_cache_relmse < 0;
  j["error_estimate"] = {{"relmse", cache_unknown ? Json(nullptr)
                                                  : Json(estimated_sampling_relmse +
                                                         std::max(0.0, estimated_cache_relmse))},
                         {"sampling_relmse", estimated_sampling_relmse},
                         {"cache_relmse", estimated_cache_relmse},
                         {"target_error", target_error}};
  if (!cache_rounds.empty()) {
    Json rounds = Json::array();
    for (const CacheRound& r : cache_rounds)
      rounds.push_back({{"accuracy", Short(r.accuracy)},
                        {"record_rays", r.record_rays},
                        {"lookup_factor", Short(r.lookup_factor)},
                        {"cache_relmse", r.error},
                        {"noise_relmse", r.noise},
                        {"share", r.share},
                        {"rebuilt", r.rebuilt},
                        {"renewed", r.renewed}});
    j["error_estimate"]["cache_rounds"] = rounds;
  }
  if (balanced)
    j["record_balance"] = {{"record_rays", balance.record_rays},
                           {"record_noise_relmse", balance.record_noise},
                           {"sampling_relmse", balance.sampling_error},
                           {"expected_spp", balance.expected_spp},
                           {"record_thread_seconds", balance.record_seconds},
                           {"sampling_thread_seconds", balance.sampling_seconds},
                           {"pilot_records", balance.pilot_records},
                           {"cache_levels", balance.cache_levels},
                           {"secondary_heavy_share", balance.secondary_heavy_share},
                           {"two_level_pilot_capped", balance.two_level_pilot_capped},
                           {"one_level_record_noise_relmse", balance.one_level_record_noise},
                           {"one_level_sampling_relmse", balance.one_level_sampling_error}};
  if (integrator_chosen)
    j["integrator_choice"] = {{"integrator", integrator},
                              {"path_per_sample_relmse", path_pilot.per_sample_error},
                              {"path_seconds_per_sample", path_pilot.seconds_per_sample},
                              {"cache_thread_seconds", denoised_choice.cache_seconds},
                              {"cache_own_relmse", denoised_choice.cache_own},
                              {"cache_sampling_relmse", denoised_choice.cache_sampling},
                              {"path_relmse", denoised_choice.path},
                              {"image_pixels", denoised_choice.image_pixels},
                              {"min_pixels", denoised_choice.min_pixels},
                              {"path_pays", denoised_choice.path_pays},
                              {"denoiser_gain", kDenoiserGain}};
  j["tiles"] = {{"count", tiles}, {"size", tile_size}};
  j["geometry"] = {{"triangles", triangles}, {"degenerate_dropped", degenerate_dropped}};
  j["environment_guide"] = {{"cells", environment_guide_cells}};
  j["image"] = {{"mean_rgb", {Short(mean_rgb.x), Short(mean_rgb.y), Short(mean_rgb.z)}},
                {"nonfinite_pixels", nonfinite_pixels}};
  j["peak_rss_mib"] = PeakRssMiB();
  j["warnings"] = warnings;
  // Invalid UTF-8 (a scene path or shape name is bytes from the user) is replaced, not thrown
  // over at the end of a render.
  return j.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
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

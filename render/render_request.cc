// RenderRequest -> RenderSettings, with the one validation (see render_request.h).
#include "render/render_request.h"

#include <cmath>
#include <initializer_list>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace irfarm {
namespace {

constexpr int kMaxThreads = 4096;

absl::Status OutOfRange(absl::string_view name, absl::string_view range, double value) {
  return absl::InvalidArgumentError(absl::StrCat(name, " must be ", range, ", got ", value));
}

// 0 (the default) or in [1, kMaxRequestCount].
absl::Status CheckCount(absl::string_view name, int v) {
  if (v < 0 || v > kMaxRequestCount) return OutOfRange(name, "in [1, 1048576] (0: the default)", v);
  return absl::OkStatus();
}

// "" (the default) or one of `options`.
absl::Status CheckChoice(absl::string_view name, const std::string& v,
                         std::initializer_list<const char*> options) {
  if (v.empty()) return absl::OkStatus();
  for (const char* o : options)
    if (v == o) return absl::OkStatus();
  return absl::InvalidArgumentError(
      absl::StrCat("unknown ", name, " '", v, "' (supported: ", absl::StrJoin(options, ", "), ")"));
}

// 0 (the default) or finite and in (0, hi].
absl::Status CheckPositive(absl::string_view name, double v, double hi, absl::string_view range) {
  if (v == 0) return absl::OkStatus();
  if (!(v > 0 && v <= hi)) return OutOfRange(name, range, v);
  return absl::OkStatus();
}

}  // namespace

absl::Status ValidateRequest(const RenderRequest& r) {
  absl::Status s = CheckChoice("integrator", r.integrator, {"irrcache", "path"});
  if (s.ok()) s = CheckCount("spp", r.spp);
  if (s.ok() && (r.threads < 0 || r.threads > kMaxThreads))
    s = OutOfRange("threads", "in [1, 4096] (0: all cores)", r.threads);
  if (s.ok()) s = CheckPositive("accuracy", r.accuracy, 1, "in (0, 1]");
  if (s.ok()) s = CheckCount("record_rays", r.record_rays);
  if (s.ok()) s = CheckCount("light_samples", r.light_samples);
  if (s.ok()) s = CheckChoice("light_sampling", r.light_sampling, {"all", "one"});
  if (s.ok()) {
    s = CheckChoice("spacing", r.spacing,
                    {RecordSpacingName(RecordSpacing::kHessian),
                     RecordSpacingName(RecordSpacing::kSplitSphere)});
  }
  if (s.ok()) s = CheckChoice("interpolation", r.interpolation, {"linear", "ward"});
  if (s.ok() && (r.cache_levels < 0 || r.cache_levels > 3))
    s = OutOfRange("cache_levels", "in [1, 3] (0: chosen per scene)", r.cache_levels);
  if (s.ok()) s = CheckPositive("min_spacing", r.min_spacing_px, 1e6, "in (0, 1e6] pixels");
  if (s.ok()) s = CheckPositive("max_spacing", r.max_spacing_px, 1e6, "in (0, 1e6] pixels");
  if (s.ok() && r.lookup_factor != 0 && !(r.lookup_factor >= 1 && r.lookup_factor <= 4))
    s = OutOfRange("lookup_factor", "in [1, 4]", r.lookup_factor);
  if (s.ok()) s = CheckChoice("adaptive", r.adaptive, {"on", "off"});
  if (s.ok()) s = CheckCount("min_spp", r.min_spp);
  if (s.ok()) s = CheckCount("max_spp", r.max_spp);
  if (s.ok()) s = CheckPositive("sampling_error", r.sampling_error, 1, "in (0, 1]");
  if (s.ok()) s = CheckPositive("target_error", r.target_error, 1, "in (0, 1]");
  if (s.ok()) s = CheckPositive("time_limit", r.time_limit, 1e6, "in (0, 1e6] seconds");
  return s;
}

absl::StatusOr<RenderSettings> SettingsFor(const SceneDesc& desc, const RenderRequest& r) {
  if (absl::Status st = ValidateRequest(r); !st.ok()) return st;
  absl::StatusOr<RenderSettings> defaults =
      SettingsForScene(desc, r.integrator.empty() ? "irrcache" : r.integrator);
  if (!defaults.ok()) return defaults.status();
  RenderSettings s = *std::move(defaults);
  IrrcacheSettings& ic = s.irrcache;
  if (r.spp > 0) s.spp = r.spp;
  s.threads = r.threads;
  s.seed = r.seed;
  if (r.accuracy > 0) ic.accuracy = r.accuracy;
  if (r.record_rays > 0) {
    ic.record_rays = r.record_rays;
    ic.balance_record_rays = false;  // the user's rays, as asked
  }
  if (r.light_samples > 0) ic.light_samples = r.light_samples;
  if (!r.light_sampling.empty()) ic.path.all_lights = r.light_sampling == "all";
  if (!r.spacing.empty()) {
    ic.spacing = r.spacing == RecordSpacingName(RecordSpacing::kHessian)
                     ? RecordSpacing::kHessian
                     : RecordSpacing::kSplitSphere;
  }
  if (!r.interpolation.empty()) ic.linear_fit = r.interpolation == "linear";
  if (r.cache_levels > 0) {
    ic.cache_levels = r.cache_levels;
    ic.choose_cache_levels = false;  // the user's levels, as asked
  }
  if (r.min_spacing_px > 0) ic.min_spacing_px = r.min_spacing_px;
  if (r.max_spacing_px > 0) ic.max_spacing_px = r.max_spacing_px;
  if (ic.min_spacing_px > ic.max_spacing_px)
    return absl::InvalidArgumentError(absl::StrCat("min_spacing (", ic.min_spacing_px,
                                                   " px) must not exceed max_spacing (",
                                                   ic.max_spacing_px, " px)"));
  if (r.lookup_factor > 0) ic.lookup_factor = r.lookup_factor;
  s.overture = r.overture;
  s.caustics = r.caustics;
  s.firefly_filter = r.firefly_filter;
  ic.direct_sun = r.direct_sun;
  if (!r.adaptive.empty()) s.adaptive = r.adaptive == "on";
  if (r.min_spp > 0) s.min_spp = r.min_spp;
  if (r.max_spp > 0) s.max_spp = r.max_spp;
  if (r.sampling_error > 0) s.sampling_error = r.sampling_error;
  if (r.time_limit > 0) s.time_limit = r.time_limit;
  if (r.target_error > 0) {
    s.target_error = r.target_error;
    s.adaptive = true;
  }
  s.record_map = r.record_map;
  s.sample_map = r.sample_map;
  s.progress = r.progress;
  s.aovs = r.aovs || r.denoise;
  // Splatted noise is shared between neighbouring pixels, which the denoiser cannot tell from
  // detail: on the living room with a gaussian filter, path 64 spp denoised 4.8e-2 splatted
  // against 1.6e-2 with each sample kept in its pixel (undenoised 5.3e-2 and 1.7e-1).
  s.splat = !r.denoise;
  // Named or not, the integrator renders the image; unnamed, a denoised image may be rendered by
  // path where the pilots find it cheaper (RenderSettings::choose_integrator).
  s.denoise = r.denoise;
  s.choose_integrator = r.integrator.empty();
  return s;
}

}  // namespace irfarm

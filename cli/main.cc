// The `irfarm` command. `render` renders a scene locally in one process (no network);
// `compare` prints the error metrics of one EXR against another (relMSE as the project defines
// it); `downsample` box-filters an EXR (for low-resolution reference images). `submit`, `status`,
// `watch`, `cancel`, `delete`, `fetch` and `snapshot` talk to a coordinator
// (cli/service_commands.h).
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <map>
#include <string>

#include "cache/snapshot.h"
#include "cli/paths.h"
#include "cli/service_commands.h"
#include "render/denoiser.h"
#include "render/image.h"
#include "render/pipeline.h"
#include "render/record_bounds.h"
#include "render/renderer.h"
#include "render/scene.h"
#include "render/scene_loader.h"
#include "service/scene_hash.h"

namespace irfarm {
namespace {

// `irfarm render`'s flags: the request (render/render_request.h, validated there, as a job's
// settings are) and what only the command has (files, the denoiser, the scene's -D defines).
struct RenderArgs {
  RenderRequest request;
  std::string scene, output = "out.exr", stats, record_map, sample_map;
  bool no_overture = false, quiet = false, env_guide = true;
  bool aovs = false;  // write the AOV layers (render/aov.h) into the output EXR
  // Default "image" for both integrators (bench/denoise_bench.py, 10 scenes with living-room):
  // demodulated was better for path at 16 spp in 5 of 10 scenes, 1.04x worse in geometric mean
  // and 1.73x worse on living-room (textured, the real interior); for irrcache image was never
  // worse by more than 2% and 1.56x better on living-room.
  std::string denoise_mode = "image";
  std::string cache_in;  // warm-start from this cache snapshot
  std::vector<std::string> defines;
};

int RunRender(const RenderArgs& args) {
  LoadOptions options;
  for (const std::string& d : args.defines) {
    const size_t eq = d.find('=');
    if (eq == std::string::npos || eq == 0) {
      std::fprintf(stderr, "error: -D expects name=value, got '%s'\n", d.c_str());
      return 2;
    }
    options.defines[d.substr(0, eq)] = d.substr(eq + 1);
  }
  RenderRequest request = args.request;
  request.overture = !args.no_overture;
  request.progress = !args.quiet;
  request.record_map = !args.record_map.empty();
  request.sample_map = !args.sample_map.empty();
  request.aovs = args.aovs;
  // Checked here as well as in PrepareRender: a bad flag is a usage error (exit 2), found before
  // the scene is read.
  if (absl::Status bad = ValidateRequest(request); !bad.ok()) {
    std::fprintf(stderr, "error: %s\n", std::string(bad.message()).c_str());
    return 2;
  }
  SceneBuildOptions build_options;
  build_options.environment_guide = args.env_guide;
  absl::StatusOr<PreparedRender> prepared =
      PrepareRender(args.scene, options, request, build_options);
  if (!prepared.ok()) {
    std::fprintf(stderr, "%s\n", std::string(prepared.status().message()).c_str());
    return 1;
  }
  const SceneDesc& desc = prepared->desc;
  const Scene& scene = *prepared->scene;
  for (const std::string& w : desc.warnings) spdlog::warn("{}", w);
  const RenderSettings& s = prepared->settings;

  // The denoiser is loaded before rendering, so that a missing one fails fast.
  std::unique_ptr<Denoiser> denoiser;
  DenoiseMode denoise_mode = DenoiseMode::kImage;
  if (request.denoise) {
    absl::StatusOr<DenoiseMode> mode = ParseDenoiseMode(args.denoise_mode);
    absl::StatusOr<std::unique_ptr<Denoiser>> d =
        mode.ok() ? Denoiser::Open(request.threads) : mode.status();
    if (!d.ok()) {
      std::fprintf(stderr, "error: %s\n", std::string(d.status().message()).c_str());
      return 1;
    }
    denoiser = std::move(*d);
    denoise_mode = *mode;
  }

  std::unique_ptr<IrradianceCache> warm_cache;
  if (!args.cache_in.empty()) {
    absl::StatusOr<Snapshot> snap = ReadSnapshotFile(args.cache_in);
    absl::Status st =
        snap.ok() ? CheckSnapshotScene(
                        *snap, CacheHash(SceneHash(desc), request.caustics, request.direct_sun),
                        args.cache_in)
                  : snap.status();
    if (!st.ok()) {
      std::fprintf(stderr, "error: %s\n", std::string(st.message()).c_str());
      return 1;
    }
    // The same bounds the coordinator holds a snapshot's records to: a record with R = 1e30
    // or a huge irradiance passes IsValidRecord and would shade every lookup.
    st = SnapshotRecordsProblem(RecordBoundsForScene(desc), snap->records, args.cache_in);
    if (!st.ok()) {
      std::fprintf(stderr, "error: %s\n", std::string(st.message()).c_str());
      return 1;
    }
    warm_cache = std::make_unique<IrradianceCache>(CacheSettingsFor(scene, s));
    for (IrradianceRecord r : snap->records) {
      r.origin = 0xffffffffu;  // not computed by this render
      warm_cache->Insert(r);
    }
  }
  RenderOutput out = Render(scene, s, warm_cache.get());
  RenderStats& st = out.stats;
  st.scene = args.scene;
  st.phases.insert(st.phases.begin(), prepared->build_time);
  st.phases.insert(st.phases.begin(), prepared->load_time);
  st.triangles = scene.counts().triangles;
  st.degenerate_dropped = scene.counts().degenerate_dropped;
  st.environment_guide_cells = scene.environment_guide().cells();
  for (const std::string& w : st.warnings) spdlog::warn("{}", w);  // the render's own
  st.warnings.insert(st.warnings.begin(), desc.warnings.begin(), desc.warnings.end());

  const std::vector<ExrLayer> layers = args.aovs ? out.aovs.Layers() : std::vector<ExrLayer>{};
  absl::Status status;
  if (denoiser) {
    PhaseTimer denoise_timer("denoise");
    const std::string noisy = StripExtension(args.output) + ".noisy.exr";
    status = WriteExr(out.image, noisy, layers);
    absl::StatusOr<Image> clean = DenoiseRender(*denoiser, out.image, out.aovs, denoise_mode);
    if (!clean.ok()) status = clean.status();
    if (status.ok()) out.image = std::move(*clean);
    st.phases.push_back(denoise_timer.Stop());
  }

  PhaseTimer write_timer("write");
  if (status.ok()) status = WriteExr(out.image, args.output, layers);
  if (status.ok()) status = WritePng(out.image, StripExtension(args.output) + ".png");
  if (status.ok() && s.sample_map) status = WritePng(out.sample_map, args.sample_map, 1.0f);
  if (status.ok() && s.record_map) {
    status = StripExtension(args.record_map) + ".exr" == args.record_map
                 ? WriteExr(out.record_map, args.record_map)
                 : WritePng(out.record_map, args.record_map);
  }
  if (!status.ok()) {
    std::fprintf(stderr, "%s\n", std::string(status.message()).c_str());
    return 1;
  }
  st.phases.push_back(write_timer.Stop());
  if (!args.stats.empty()) {
    status = WriteTextFile(args.stats, st.ToJson());
    if (!status.ok()) {
      std::fprintf(stderr, "%s\n", std::string(status.message()).c_str());
      return 1;
    }
  }
  if (!args.quiet)
    std::fprintf(stderr, "%s: %dx%d %s spp=%d in %.2fs (render %.2fs), records %llu\n",
                 args.output.c_str(), st.width, st.height, st.integrator.c_str(), st.spp,
                 st.PhaseWall("pilot") + st.PhaseWall("overture") + st.PhaseWall("render"),
                 st.PhaseWall("render"),
                 static_cast<unsigned long long>(st.counters.records_computed));
  return 0;
}

int RunCompare(const std::string& test_path, const std::string& ref_path) {
  absl::StatusOr<Image> test = ReadExr(test_path);
  absl::StatusOr<Image> ref = ReadExr(ref_path);
  if (!test.ok() || !ref.ok()) {
    std::fprintf(stderr, "%s\n",
                 std::string((test.ok() ? ref.status() : test.status()).message()).c_str());
    return 1;
  }
  if (test->width != ref->width || test->height != ref->height) {
    std::fprintf(stderr, "error: sizes differ: %dx%d vs %dx%d\n", test->width, test->height,
                 ref->width, ref->height);
    return 1;
  }
  const ImageError e = CompareImages(*test, *ref);
  // nlohmann-json: a non-finite figure is written as null, never as bare "nan".
  const nlohmann::ordered_json j = {{"relmse", e.relmse},
                                    {"rmse", e.rmse},
                                    {"mean_test", {e.mean_test.x, e.mean_test.y, e.mean_test.z}},
                                    {"mean_ref", {e.mean_ref.x, e.mean_ref.y, e.mean_ref.z}},
                                    {"nonfinite_pixels", e.nonfinite}};
  std::printf("%s\n", j.dump().c_str());
  return 0;
}

// Denoises an EXR written with --aovs (the layers guide the filter); prints the seconds taken.
int RunDenoise(const std::string& in, const std::string& out, const std::string& mode_name,
               bool prefilter) {
  absl::StatusOr<DenoiseMode> mode = ParseDenoiseMode(mode_name);
  absl::StatusOr<Image> image = ReadExr(in);
  absl::StatusOr<AovImages> aovs = AovImages::Read(in);
  absl::Status st = !mode.ok() ? mode.status() : !image.ok() ? image.status() : aovs.status();
  if (!st.ok()) {
    std::fprintf(stderr, "error: %s\n", std::string(st.message()).c_str());
    return 1;
  }
  absl::StatusOr<std::unique_ptr<Denoiser>> denoiser = Denoiser::Open();
  if (!denoiser.ok()) {
    std::fprintf(stderr, "error: %s\n", std::string(denoiser.status().message()).c_str());
    return 1;
  }
  PhaseTimer timer("denoise");
  absl::StatusOr<Image> clean = DenoiseRender(**denoiser, *image, *aovs, *mode, prefilter);
  const PhaseTime t = timer.Stop();
  st = clean.ok() ? WriteExr(*clean, out, aovs->Layers()) : clean.status();
  if (!st.ok()) {
    std::fprintf(stderr, "error: %s\n", std::string(st.message()).c_str());
    return 1;
  }
  std::printf("%s\n", nlohmann::json{{"denoise_seconds", t.wall_seconds}}.dump().c_str());
  return 0;
}

int RunDownsample(const std::string& in, const std::string& out, int factor) {
  absl::StatusOr<Image> image = ReadExr(in);
  if (!image.ok()) {
    std::fprintf(stderr, "%s\n", std::string(image.status().message()).c_str());
    return 1;
  }
  if (factor < 1 || image->width % factor || image->height % factor) {
    std::fprintf(stderr, "error: factor %d does not divide %dx%d\n", factor, image->width,
                 image->height);
    return 2;
  }
  const absl::Status st = WriteExr(Downsample(*image, factor), out);
  if (!st.ok()) {
    std::fprintf(stderr, "%s\n", std::string(st.message()).c_str());
    return 1;
  }
  return 0;
}

}  // namespace
}  // namespace irfarm

int main(int argc, char** argv) {
  using irfarm::RenderArgs;
  CLI::App app{"irfarm: irradiance-caching renderer"};
  app.require_subcommand(1);

  RenderArgs ra;
  CLI::App* render = app.add_subcommand("render", "render a Mitsuba 3 XML scene locally");
  render->add_option("scene", ra.scene, "scene.xml")->required()->check(CLI::ExistingFile);
  render->add_option("-o,--output", ra.output, "output EXR (a PNG preview is written beside it)");
  // Values are checked by ValidateRequest (render/render_request.h), the same check a job's
  // settings get, not here: one validation, one message.
  irfarm::RenderRequest& rq = ra.request;
  render->add_option("--integrator", rq.integrator,
                     "path or irrcache (default irrcache; with --denoise, path where the pilots "
                     "predict it the better once denoised)");
  render->add_option("--spp", rq.spp, "samples per pixel (adaptive: on average)");
  render->add_option("--accuracy", rq.accuracy, "irrcache: Ward's a, (0, 1] (default 0.1)");
  render->add_option("--record-rays", rq.record_rays, "irrcache: hemisphere rays per record");
  render->add_option("--light-samples", rq.light_samples, "irrcache: direct samples per hit");
  render->add_option("--cache-levels", rq.cache_levels,
                     "irrcache: 1 = records' rays are path traced; 2 = they use a second-level "
                     "cache at the surfaces they reach; 3 = that level's rays a third (default: "
                     "chosen per scene by the pilots)");
  render->add_option("--light-sampling", rq.light_sampling,
                     "next-event estimation along paths: all (every light at each vertex, the "
                     "default) or one (one light picked by its unoccluded contribution)");
  CLI::Option* spacing = render->add_option(
      "--spacing", rq.spacing,
      "irrcache: record radii by hessian (the record's own derivatives; default) or "
      "split-sphere (Ward's, for comparison)");
  CLI::Option* interpolation =
      render->add_option("--interpolation", rq.interpolation,
                         "irrcache: lookups take the plane fitted to the records that count "
                         "(linear, the default) or their weighted mean (ward, for comparison)");
  render->add_option("--min-spacing", rq.min_spacing_px, "irrcache: min validity radius, pixels");
  render->add_option("--max-spacing", rq.max_spacing_px, "irrcache: max validity radius, pixels");
  CLI::Option* lookup_factor = render->add_option(
      "--lookup-factor", rq.lookup_factor,
      "irrcache: camera lookups weigh records out to eps < a x this, in [1, 4] (default 1.5; "
      "1 = Ward's rule; --target-error uses 1)");
  render->add_flag("--no-overture", ra.no_overture, "irrcache: skip the cache-filling prepass");
  render->add_flag(
      "--caustics,!--no-caustics", rq.caustics,
      "irrcache: caustics (light through mirrors, smooth glass and sharp metals) from a photon map "
      "instead of the records (the default; --no-caustics leaves them to the records)");
  render->add_flag("--direct-sun,!--no-direct-sun", rq.direct_sun,
                   "an environment map's sun sampled as direct light at every diffuse or glossy "
                   "vertex, not left to the records (irrcache) or to the environment's own samples "
                   "(path); the default where the map has a compact sun");
  render->add_flag("--firefly-filter,!--no-firefly-filter", rq.firefly_filter,
                   "spread a pixel's one sample that outweighs all its others and every "
                   "neighbouring pixel over the 5 x 5 pixels around it, keeping the image's energy "
                   "(the default)");
  render->add_flag("--env-guide,!--no-env-guide", ra.env_guide,
                   "environment samples drawn partly towards where the environment was seen from "
                   "nearby (windows; the default where the scene has an environment light)");
  render->add_option("--threads", rq.threads, "threads (default: all cores)");
  render->add_option("--seed", rq.seed, "random seed");
  render->add_option("--stats", ra.stats, "write the stats JSON here");
  render->add_option("--record-map", ra.record_map, "write an image marking computed records");
  render->add_option("--sample-map", ra.sample_map,
                     "write a PNG of the samples each pixel got (dark: few, white: --spp)");
  render->add_option("--adaptive", rq.adaptive,
                     "adaptive sampling on|off (default: on for irrcache, off for path)");
  render->add_option("--min-spp", rq.min_spp, "adaptive: samples every pixel gets first (16)");
  render->add_option("--max-spp", rq.max_spp,
                     "adaptive: the most samples one pixel gets (default 16 x --spp)");
  render->add_option("--sampling-error", rq.sampling_error,
                     "adaptive: the image's estimated sampling relMSE to stop at");
  render
      ->add_option("--target-error", rq.target_error,
                   "stop when the estimated relMSE (cache + sampling) reaches this (or "
                   "--time-limit); no sample budget then")
      ->excludes(lookup_factor)
      ->excludes(spacing)
      ->excludes(interpolation);
  render->add_option("--time-limit", rq.time_limit, "stop adding samples after this many seconds");
  render->add_option("-D", ra.defines, "name=value for the scene's <default>s");
  render->add_flag("-q,--quiet", ra.quiet, "no progress or summary on stderr");
  render->add_flag("--aovs", ra.aovs,
                   "add layers albedo, normal, depth, emission, direct, indirect, variance "
                   "to the EXR");
  render->add_flag("--denoise", rq.denoise,
                   "denoise with Open Image Denoise (OUT.exr), keep the render as OUT.noisy.exr");
  render
      ->add_option("--denoise-mode", ra.denoise_mode,
                   "image (default), demodulated (by albedo) "
                   "or indirect (only)")
      ->check(CLI::IsMember({"image", "demodulated", "indirect"}));
  render->add_option("--cache-in", ra.cache_in, "warm-start from this cache snapshot file")
      ->check(CLI::ExistingFile);

  // Service subcommands: each talks to a coordinator.
  const std::string default_coordinator = irfarm::DefaultCoordinator();
  irfarm::SubmitArgs sa;
  sa.coordinator.address = default_coordinator;
  irfarm::ServiceConnection conn{default_coordinator, {}};
  // --coordinator and the credentials (--token-file or $IRFARM_TOKEN, TLS) of a subcommand.
  const auto add_connection = [](CLI::App* sub, irfarm::ServiceConnection* c) {
    sub->add_option("--coordinator", c->address,
                    "coordinator address, or several separated by commas (active and standbys)");
    sub->add_option("--token-file", c->auth.token_file, "client token file ($IRFARM_TOKEN)");
    sub->add_option("--tls-ca", c->auth.tls_ca, "use TLS, trusting this CA (PEM)");
    sub->add_option("--tls-cert", c->auth.tls_cert, "client certificate (mutual TLS, PEM)");
    sub->add_option("--tls-key", c->auth.tls_key, "client key (mutual TLS, PEM)");
  };
  CLI::App* submit = app.add_subcommand("submit", "submit scenes as jobs to a coordinator");
  submit->add_option("scenes", sa.scenes, "scene.xml files (a batch, queued by priority)")
      ->required()
      ->check(CLI::ExistingFile);
  add_connection(submit, &sa.coordinator);
  submit->add_option("--priority", sa.priority, "higher runs first (0-100, default 50)");
  CLI::Option* wait = submit->add_flag("--wait", sa.wait, "follow progress until the jobs end");
  // Without --wait nothing would be written, and the command would still succeed.
  submit->add_option("-o,--output", sa.output, "with --wait: write the image(s) here")->needs(wait);
  submit->add_option("--cache-in", sa.cache_in, "warm-start from this cache snapshot")
      ->check(CLI::ExistingFile);
  submit->add_option("--integrator", sa.integrator, "path or irrcache (default irrcache)");
  submit->add_option("--spp", sa.spp, "samples per pixel");
  submit->add_option("--accuracy", sa.accuracy, "irrcache: Ward's a");
  submit->add_option("--record-rays", sa.record_rays, "irrcache: hemisphere rays per record");
  submit->add_option("--tile-size", sa.tile_size, "tile edge in pixels (default 32)");
  submit->add_option("--seed", sa.seed, "random seed");
  submit->add_flag("--no-share", sa.no_share, "do not share records between workers");
  submit->add_flag("--no-overture", sa.no_overture, "irrcache: skip the per-tile prepass");
  submit->add_flag("--no-firefly-filter", sa.no_firefly_filter,
                   "leave fireflies in their pixels (default: spread over the 5 x 5 around them)");
  submit->add_flag("--no-caustics", sa.no_caustics,
                   "irrcache: leave caustics to the records (default: a photon map per job)");
  submit
      ->add_option("--target-error", sa.target_error,
                   "each tile stops adding samples when its estimated relMSE reaches this")
      ->check(CLI::Range(0.0, 1.0));
  submit
      ->add_option("--time-limit", sa.tile_time_limit,
                   "wall seconds a worker may spend on one tile")
      ->check(CLI::Range(0.0, 1e6));
  submit->add_flag("--denoise", sa.denoise,
                   "the coordinator denoises the image (Open Image Denoise); the EXR keeps the "
                   "render as layer 'noisy'");
  submit->add_flag("--shared-path", sa.shared_path,
                   "send the scene path (readable by coordinator and workers), not a bundle");
  submit->add_option("-D", sa.defines, "name=value for the scene's <default>s");
  submit->add_flag("-q,--quiet", sa.quiet, "no progress on stderr");

  std::string job_id, job_out;
  bool status_json = false, status_workers = false;
  CLI::App* status = app.add_subcommand("status", "show jobs (all, or one) with progress");
  status->add_option("job", job_id, "job id");
  add_connection(status, &conn);
  status->add_flag("--json", status_json, "print each job as JSON (with per-worker stats)");
  status->add_flag("--workers", status_workers, "show the workers (quarantine) and counters");
  CLI::App* cancel = app.add_subcommand("cancel", "cancel a job");
  cancel->add_option("job", job_id, "job id")->required();
  add_connection(cancel, &conn);
  CLI::App* del = app.add_subcommand("delete", "remove a finished job (image, tiles, records)");
  del->add_option("job", job_id, "job id")->required();
  add_connection(del, &conn);
  CLI::App* watch = app.add_subcommand("watch", "follow a job with a progress bar until it ends");
  watch->add_option("job", job_id, "job id")->required();
  add_connection(watch, &conn);
  CLI::App* fetch = app.add_subcommand("fetch", "download a finished job's EXR");
  fetch->add_option("job", job_id, "job id")->required();
  fetch->add_option("-o,--output", job_out, "output EXR")->required();
  add_connection(fetch, &conn);
  CLI::App* snapshot = app.add_subcommand("snapshot", "export a job's irradiance cache to a file");
  snapshot->add_option("job", job_id, "job id")->required();
  snapshot->add_option("-o,--output", job_out, "snapshot file")->required();
  add_connection(snapshot, &conn);

  std::string cmp_test, cmp_ref;
  CLI::App* compare = app.add_subcommand("compare", "error metrics of an EXR against a reference");
  compare->add_option("test", cmp_test)->required();
  compare->add_option("reference", cmp_ref)->required();

  std::string dn_in, dn_out, dn_mode = "image";
  bool dn_prefilter = false;
  CLI::App* denoise =
      app.add_subcommand("denoise", "denoise an EXR rendered with --aovs (Open Image Denoise)");
  denoise->add_option("input", dn_in)->required()->check(CLI::ExistingFile);
  denoise->add_option("output", dn_out)->required();
  denoise->add_option("--mode", dn_mode, "image (default), demodulated or indirect");
  denoise->add_flag("--prefilter", dn_prefilter, "denoise the albedo and normal guides first");

  std::string ds_in, ds_out;
  int ds_factor = 4;
  CLI::App* downsample =
      app.add_subcommand("downsample", "box-filter an EXR down by an integer factor");
  downsample->add_option("input", ds_in)->required();
  downsample->add_option("output", ds_out)->required();
  downsample->add_option("--factor", ds_factor, "pixels per output pixel along each axis");

  CLI11_PARSE(app, argc, argv);
  if (render->parsed()) return irfarm::RunRender(ra);
  if (compare->parsed()) return irfarm::RunCompare(cmp_test, cmp_ref);
  if (denoise->parsed()) return irfarm::RunDenoise(dn_in, dn_out, dn_mode, dn_prefilter);
  if (downsample->parsed()) return irfarm::RunDownsample(ds_in, ds_out, ds_factor);
  if (submit->parsed()) return irfarm::RunSubmit(sa);
  if (status->parsed()) return irfarm::RunStatus(conn, job_id, status_json, status_workers);
  if (cancel->parsed()) return irfarm::RunCancel(conn, job_id);
  if (del->parsed()) return irfarm::RunDelete(conn, job_id);
  if (watch->parsed()) return irfarm::RunWatch(conn, job_id);
  if (fetch->parsed()) return irfarm::RunFetch(conn, job_id, job_out);
  if (snapshot->parsed()) return irfarm::RunSnapshot(conn, job_id, job_out);
  return 2;
}

// Fuzz target: the coordinator's job API request handling (JobManager::Submit, then GetJob,
// ExportSnapshot and Cancel of what it accepted) on a serialized SubmitJobRequest from a
// non-admin client: settings, defines, bundles (paths, file contents, the main file) and cache
// snapshots. Every answer must be a job or a status; accepted jobs are cancelled so that the live
// job limit never hides the paths behind it.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "coordinator/in_memory_job_store.h"
#include "coordinator/job_manager.h"

namespace {

struct Harness {
  irfarm::InMemoryJobStore store;
  std::unique_ptr<irfarm::JobManager> manager;
  Harness() {
    irfarm::JobManagerOptions options;
    options.max_upload_bytes = size_t(1) << 20;
    options.limits.max_film_pixels = int64_t(1) << 20;
    manager = std::move(*irfarm::JobManager::Create(options, &store));
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Harness* h = new Harness();  // one coordinator for the whole run
  irfarm::v1::SubmitJobRequest req;
  if (!req.ParseFromArray(data, int(size))) return 0;
  const irfarm::Caller caller{"fuzz", false};
  absl::StatusOr<irfarm::v1::Job> job = h->manager->Submit(req, caller);
  if (!job.ok()) return 0;
  if (!h->manager->GetJob(job->id(), caller).ok()) __builtin_trap();
  (void)h->manager->ExportSnapshot(job->id(), caller);
  if (!h->manager->Cancel(job->id(), caller).ok()) __builtin_trap();
  return 0;
}

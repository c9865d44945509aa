// Fuzz target: the coordinator's worker-message handlers (JobManager::AddRecords, CompleteTile,
// FailTile, Drain), as WorkerService calls them for each message of a Session stream. The input
// is a serialized WorkerMessage from a registered worker of a coordinator (in-memory store) with
// a running 32x32 cornell-box job of 4 tiles. So that the fuzzer reaches the paths behind the
// lease check, an empty lease token stands for the lease the worker holds now (and its tile) and
// an empty job id for the job it works on. The harness keeps one coordinator across inputs (a new
// job when one ends, a new worker when one is expelled), like a long-lived coordinator facing one
// hostile worker.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "coordinator/in_memory_job_store.h"
#include "coordinator/job_manager.h"
#include "service/scene_bundle.h"

namespace {

using irfarm::v1::WorkerMessage;

struct Harness {
  irfarm::InMemoryJobStore store;
  std::unique_ptr<irfarm::JobManager> manager;
  irfarm::v1::SubmitJobRequest request;
  uint32_t worker = 0;
  std::string job;
  std::string lease;  // token bytes
  int tile = 0;

  Harness() {
    irfarm::JobManagerOptions options;
    options.quarantine_time = std::chrono::milliseconds(0);
    manager = std::move(*irfarm::JobManager::Create(options, &store));
    *request.mutable_scene()->mutable_bundle() =
        *irfarm::MakeBundle(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml");
    (*request.mutable_settings()->mutable_defines())["resx"] = "32";
    (*request.mutable_settings()->mutable_defines())["resy"] = "32";
    request.mutable_settings()->set_tile_size(16);
    request.mutable_settings()->set_share_records(true);
    worker = manager->RegisterWorker("fuzz");
  }
  // A running job with a lease held by the worker, as far as the coordinator gives one.
  void Refresh() {
    absl::StatusOr<irfarm::v1::Job> j = manager->GetJob(job);
    if (job.empty() || !j.ok() || j->state() >= irfarm::v1::JOB_STATE_SUCCEEDED) {
      absl::StatusOr<irfarm::v1::Job> submitted = manager->Submit(request);
      if (!submitted.ok()) __builtin_trap();
      job = submitted->id();
    }
    if (manager->Expelled(worker)) {
      manager->WorkerGone(worker, "expelled");
      worker = manager->RegisterWorker("fuzz");
    }
    for (const irfarm::v1::CoordinatorMessage& m :
         manager->Poll(worker, std::chrono::milliseconds(0)))
      if (m.has_lease()) {
        lease = m.lease().lease_token();
        tile = m.lease().tile_index();
        job = m.lease().job_id();
      }
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Harness* h = new Harness();  // one coordinator for the whole run (see above)
  WorkerMessage m;
  if (!m.ParseFromArray(data, int(size))) return 0;
  h->Refresh();
  h->manager->Heard(h->worker);
  switch (m.msg_case()) {
    case WorkerMessage::kRecords:
      if (m.records().job_id().empty()) m.mutable_records()->set_job_id(h->job);
      (void)h->manager->AddRecords(h->worker, m.records());
      break;
    case WorkerMessage::kTileResult:
      if (m.tile_result().lease_token().empty()) {
        m.mutable_tile_result()->set_lease_token(h->lease);
        m.mutable_tile_result()->set_tile_index(h->tile);
      }
      if (m.tile_result().job_id().empty()) m.mutable_tile_result()->set_job_id(h->job);
      (void)h->manager->CompleteTile(h->worker, m.tile_result());
      break;
    case WorkerMessage::kTileFailed:
      if (m.tile_failed().lease_token().empty()) {
        m.mutable_tile_failed()->set_lease_token(h->lease);
        m.mutable_tile_failed()->set_tile_index(h->tile);
      }
      if (m.tile_failed().job_id().empty()) m.mutable_tile_failed()->set_job_id(h->job);
      (void)h->manager->FailTile(h->worker, m.tile_failed());
      break;
    default:
      break;
  }
  // What the worker may see and a client may ask must stay answerable.
  (void)h->manager->Cluster();
  (void)h->manager->ListJobs();
  return 0;
}

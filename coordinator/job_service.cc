// JobServiceImpl: proto <-> JobManager translation (see job_service.h).
#include "coordinator/job_service.h"

#include <algorithm>
#include <chrono>
#include <thread>

#include "service/grpc_status.h"

namespace irfarm {
namespace {

constexpr size_t kChunkBytes = size_t(1) << 20;  // streamed files go in 1 MiB pieces

template <typename Response>
grpc::Status StreamBytes(const absl::StatusOr<std::string>& bytes,
                         grpc::ServerWriter<Response>* writer) {
  if (!bytes.ok()) return ToGrpcStatus(bytes.status());
  for (size_t o = 0; o < bytes->size(); o += kChunkBytes) {
    Response r;
    r.set_chunk(bytes->substr(o, std::min(kChunkBytes, bytes->size() - o)));
    if (!writer->Write(r)) return grpc::Status(grpc::StatusCode::CANCELLED, "client went away");
  }
  return grpc::Status::OK;
}

// Gives a download or watch slot (JobServiceImpl::TakeSlot) back when the call ends.
struct Slot {
  std::atomic<int>* in_use;
  ~Slot() { in_use->fetch_sub(1); }
};

grpc::Status DownloadsBusy(int limit) {
  return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                      std::to_string(limit) +
                          " result and snapshot downloads are in progress (--max-downloads); "
                          "retry when one has finished");
}

bool IsFinal(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
}

}  // namespace

JobServiceImpl::JobServiceImpl(JobManager* manager, Authenticator* auth)
    : manager_(manager), auth_(auth) {
  const char* names[kNumMethods] = {"SubmitJob", "GetJob",      "ListJobs",   "CancelJob",
                                    "GetResult", "ExportCache", "GetCluster", "DeleteJob"};
  for (int i = 0; i < kNumMethods; ++i)
    latency_[i] = manager->metrics_registry()->AddHistogram(
        "irfarm_rpc_duration_seconds", "gRPC call handling time at the coordinator.",
        LatencyBuckets(), {{"method", names[i]}});
}

absl::StatusOr<Caller> JobServiceImpl::Authenticate(const grpc::ServerContext* context) {
  if (auth_ == nullptr) return Caller();
  return auth_->Client(*context);
}

#define IRFARM_AUTHENTICATE(caller)                                 \
  absl::StatusOr<Caller> caller##_or = Authenticate(context);       \
  if (!caller##_or.ok()) return ToGrpcStatus(caller##_or.status()); \
  const Caller& caller = *caller##_or

grpc::Status JobServiceImpl::SubmitJob(grpc::ServerContext* context,
                                       const v1::SubmitJobRequest* request,
                                       v1::SubmitJobResponse* response) {
  ScopedTimer timer(latency_[kSubmit]);
  IRFARM_AUTHENTICATE(caller);
  absl::StatusOr<v1::Job> job = manager_->Submit(*request, caller);
  if (!job.ok()) return ToGrpcStatus(job.status());
  *response->mutable_job() = *job;
  return grpc::Status::OK;
}

grpc::Status JobServiceImpl::GetJob(grpc::ServerContext* context, const v1::GetJobRequest* request,
                                    v1::GetJobResponse* response) {
  ScopedTimer timer(latency_[kGet]);
  IRFARM_AUTHENTICATE(caller);
  absl::StatusOr<v1::Job> job = manager_->GetJob(request->job_id(), caller);
  if (!job.ok()) return ToGrpcStatus(job.status());
  *response->mutable_job() = *job;
  return grpc::Status::OK;
}

grpc::Status JobServiceImpl::ListJobs(grpc::ServerContext* context, const v1::ListJobsRequest*,
                                      v1::ListJobsResponse* response) {
  ScopedTimer timer(latency_[kList]);
  IRFARM_AUTHENTICATE(caller);
  for (v1::Job& job : manager_->ListJobs(caller)) *response->add_jobs() = std::move(job);
  return grpc::Status::OK;
}

grpc::Status JobServiceImpl::WatchJob(grpc::ServerContext* context,
                                      const v1::WatchJobRequest* request,
                                      grpc::ServerWriter<v1::WatchJobResponse>* writer) {
  IRFARM_AUTHENTICATE(caller);
  const int limit = manager_->options().limits.max_watches;
  if (!TakeSlot(watches_, limit))
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        std::to_string(limit) +
                            " job watches are open (--max-watches); poll GetJob, or retry "
                            "when one has ended");
  const Slot slot{&watches_};
  uint64_t version = 0;
  std::string last;
  auto looked = std::chrono::steady_clock::now() - std::chrono::milliseconds(100);
  while (!context->IsCancelled()) {
    // At most 10 looks a second: every record batch of a running job is a change, and each look
    // reads the job under the coordinator's lock.
    std::this_thread::sleep_until(looked + std::chrono::milliseconds(100));
    looked = std::chrono::steady_clock::now();
    absl::StatusOr<v1::Job> job = manager_->GetJob(request->job_id(), caller);
    if (!job.ok()) return ToGrpcStatus(job.status());
    job->clear_elapsed_seconds();  // only send when something else changed
    std::string now = job->SerializeAsString();
    if (now != last) {
      v1::WatchJobResponse r;
      *r.mutable_job() = *job;
      r.mutable_job()->set_elapsed_seconds(
          manager_->GetJob(request->job_id(), caller).value_or(*job).elapsed_seconds());
      if (!writer->Write(r)) break;
      last = std::move(now);
    }
    if (IsFinal(job->state())) break;
    version = manager_->WaitForChange(version, std::chrono::milliseconds(500));
  }
  return grpc::Status::OK;
}

grpc::Status JobServiceImpl::CancelJob(grpc::ServerContext* context,
                                       const v1::CancelJobRequest* request,
                                       v1::CancelJobResponse* response) {
  ScopedTimer timer(latency_[kCancel]);
  IRFARM_AUTHENTICATE(caller);
  absl::StatusOr<v1::Job> job = manager_->Cancel(request->job_id(), caller);
  if (!job.ok()) return ToGrpcStatus(job.status());
  *response->mutable_job() = *job;
  return grpc::Status::OK;
}

bool JobServiceImpl::TakeSlot(std::atomic<int>& in_use, int limit) {
  int n = in_use.load();
  do {
    if (n >= limit) return false;
  } while (!in_use.compare_exchange_weak(n, n + 1));
  return true;
}

grpc::Status JobServiceImpl::GetResult(grpc::ServerContext* context,
                                       const v1::GetResultRequest* request,
                                       grpc::ServerWriter<v1::GetResultResponse>* writer) {
  ScopedTimer timer(latency_[kResult]);
  IRFARM_AUTHENTICATE(caller);
  if (!TakeSlot(downloads_, manager_->options().limits.max_downloads))
    return DownloadsBusy(manager_->options().limits.max_downloads);
  const Slot slot{&downloads_};
  return StreamBytes(manager_->ResultExr(request->job_id(), caller), writer);
}

grpc::Status JobServiceImpl::ExportCache(grpc::ServerContext* context,
                                         const v1::ExportCacheRequest* request,
                                         grpc::ServerWriter<v1::ExportCacheResponse>* writer) {
  ScopedTimer timer(latency_[kExport]);
  IRFARM_AUTHENTICATE(caller);
  if (!TakeSlot(downloads_, manager_->options().limits.max_downloads))
    return DownloadsBusy(manager_->options().limits.max_downloads);
  const Slot slot{&downloads_};
  return StreamBytes(manager_->ExportSnapshot(request->job_id(), caller), writer);
}

grpc::Status JobServiceImpl::GetCluster(grpc::ServerContext* context, const v1::GetClusterRequest*,
                                        v1::GetClusterResponse* response) {
  ScopedTimer timer(latency_[kCluster]);
  IRFARM_AUTHENTICATE(caller);
  *response = manager_->Cluster(caller);
  if (auth_ != nullptr) response->set_auth_failures(auth_->failures());
  return grpc::Status::OK;
}

grpc::Status JobServiceImpl::DeleteJob(grpc::ServerContext* context,
                                       const v1::DeleteJobRequest* request,
                                       v1::DeleteJobResponse*) {
  ScopedTimer timer(latency_[kDelete]);
  IRFARM_AUTHENTICATE(caller);
  return ToGrpcStatus(manager_->Delete(request->job_id(), caller));
}

}  // namespace irfarm

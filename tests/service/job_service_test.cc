// Bad requests against the real coordinator services, in-process over a loopback port: each gets
// the right gRPC status and changes nothing. Also a worker that sends invalid records (NaN,
// non-unit normal) through a real Session stream: those are rejected and counted, the rest kept.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <thread>

#include "coordinator/in_memory_job_store.h"
#include "coordinator/job_manager.h"
#include "coordinator/job_service.h"
#include "coordinator/worker_service.h"
#include "irfarm/v1/jobs.grpc.pb.h"
#include "irfarm/v1/worker.grpc.pb.h"
#include "service/record_codec.h"
#include "service/scene_bundle.h"

namespace irfarm {
namespace {

const std::string kScene = std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml";

class JobServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    JobManagerOptions options;
    options.max_upload_bytes = size_t(1) << 20;
    manager_ = std::move(*JobManager::Create(options, &store_));
    jobs_ = std::make_unique<JobServiceImpl>(manager_.get());
    workers_ = std::make_unique<WorkerServiceImpl>(manager_.get());
    grpc::ServerBuilder b;
    int port = 0;
    b.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    b.SetMaxReceiveMessageSize(8 << 20);
    b.RegisterService(jobs_.get());
    b.RegisterService(workers_.get());
    server_ = b.BuildAndStart();
    ASSERT_GT(port, 0);
    grpc::ChannelArguments args;
    args.SetMaxSendMessageSize(-1);
    channel_ = grpc::CreateCustomChannel("127.0.0.1:" + std::to_string(port),
                                         grpc::InsecureChannelCredentials(), args);
    stub_ = v1::JobService::NewStub(channel_);
  }
  void TearDown() override { server_->Shutdown(std::chrono::system_clock::now()); }

  grpc::Status Submit(const v1::SubmitJobRequest& req, v1::SubmitJobResponse* resp) {
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
    return stub_->SubmitJob(&c, req, resp);
  }
  int NumJobs() {
    grpc::ClientContext c;
    v1::ListJobsResponse r;
    EXPECT_TRUE(stub_->ListJobs(&c, v1::ListJobsRequest(), &r).ok());
    return r.jobs_size();
  }
  v1::SubmitJobRequest GoodRequest() {
    v1::SubmitJobRequest req;
    *req.mutable_scene()->mutable_bundle() = *MakeBundle(kScene);
    (*req.mutable_settings()->mutable_defines())["resx"] = "32";
    (*req.mutable_settings()->mutable_defines())["resy"] = "32";
    req.mutable_settings()->set_share_records(true);
    return req;
  }

  InMemoryJobStore store_;
  std::unique_ptr<JobManager> manager_;
  std::unique_ptr<JobServiceImpl> jobs_;
  std::unique_ptr<WorkerServiceImpl> workers_;
  std::unique_ptr<grpc::Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::JobService::Stub> stub_;
};

TEST_F(JobServiceTest, UnknownJobIsNotFound) {
  grpc::ClientContext c1, c2, c3;
  v1::GetJobRequest g;
  g.set_job_id("job-404");
  v1::GetJobResponse gr;
  EXPECT_EQ(stub_->GetJob(&c1, g, &gr).error_code(), grpc::StatusCode::NOT_FOUND);
  v1::CancelJobRequest cr;
  cr.set_job_id("job-404");
  v1::CancelJobResponse crr;
  EXPECT_EQ(stub_->CancelJob(&c2, cr, &crr).error_code(), grpc::StatusCode::NOT_FOUND);
  v1::GetResultRequest rr;
  rr.set_job_id("job-404");
  auto reader = stub_->GetResult(&c3, rr);
  v1::GetResultResponse chunk;
  while (reader->Read(&chunk)) {
  }
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(NumJobs(), 0);
}

TEST_F(JobServiceTest, MalformedSceneIsInvalidArgumentWithFileLine) {
  v1::SubmitJobRequest req = GoodRequest();
  req.mutable_scene()->mutable_bundle()->mutable_files(0)->set_content(
      "<scene version=\"3.0.0\">\n  <bsdf type=\"measured\" id=\"x\"/>\n</scene>\n");
  v1::SubmitJobResponse resp;
  const grpc::Status st = Submit(req, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("scene.xml:2"), std::string::npos) << st.error_message();
  EXPECT_EQ(NumJobs(), 0);
}

TEST_F(JobServiceTest, TargetErrorAndTimeLimitOutOfRangeAreInvalidArgument) {
  for (int k = 0; k < 3; ++k) {
    v1::SubmitJobRequest req = GoodRequest();
    if (k == 0) req.mutable_settings()->set_target_error(2);
    if (k == 1) req.mutable_settings()->set_target_error(std::nan(""));
    if (k == 2) req.mutable_settings()->set_tile_time_limit(-1);
    v1::SubmitJobResponse resp;
    const grpc::Status st = Submit(req, &resp);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << k;
    EXPECT_NE(st.error_message().find(k == 2 ? "tile_time_limit" : "target_error"),
              std::string::npos)
        << st.error_message();
  }
  EXPECT_EQ(NumJobs(), 0);
  // In range, the job is taken.
  v1::SubmitJobRequest req = GoodRequest();
  req.mutable_settings()->set_target_error(2e-3);
  req.mutable_settings()->set_tile_time_limit(30);
  v1::SubmitJobResponse resp;
  EXPECT_TRUE(Submit(req, &resp).ok());
  EXPECT_EQ(NumJobs(), 1);
}

TEST_F(JobServiceTest, BundlePathLeavingTheBundleIsInvalidArgument) {
  for (const std::string path : {"../etc/passwd", "/etc/passwd", "meshes/../../x.obj"}) {
    v1::SubmitJobRequest req = GoodRequest();
    v1::BundleFile* f = req.mutable_scene()->mutable_bundle()->add_files();
    f->set_path(path);
    f->set_content("x");
    v1::SubmitJobResponse resp;
    const grpc::Status st = Submit(req, &resp);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << path;
    EXPECT_NE(st.error_message().find(path), std::string::npos) << st.error_message();
  }
  EXPECT_EQ(NumJobs(), 0);
}

TEST_F(JobServiceTest, UploadOverTheLimitIsResourceExhausted) {
  v1::SubmitJobRequest req = GoodRequest();
  v1::BundleFile* f = req.mutable_scene()->mutable_bundle()->add_files();
  f->set_path("big.bin");
  f->set_content(std::string(size_t(2) << 20, 'x'));  // limit is 1 MiB here
  v1::SubmitJobResponse resp;
  EXPECT_EQ(Submit(req, &resp).error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_EQ(NumJobs(), 0);
}

TEST_F(JobServiceTest, InvalidRecordsFromAWorkerAreRejectedAndCounted) {
  v1::SubmitJobResponse submitted;
  ASSERT_TRUE(Submit(GoodRequest(), &submitted).ok());
  const std::string job_id = submitted.job().id();

  auto worker_stub = v1::WorkerService::NewStub(channel_);
  grpc::ClientContext c;
  auto stream = worker_stub->Session(&c);
  v1::WorkerMessage reg;
  reg.mutable_register_()->set_name("test-worker");
  ASSERT_TRUE(stream->Write(reg));
  v1::CoordinatorMessage m;
  ASSERT_TRUE(stream->Read(&m));
  ASSERT_TRUE(m.has_registered());
  // Wait for the job spec and a lease (the worker is attached to the job then).
  bool leased = false;
  while (!leased && stream->Read(&m)) leased = m.has_lease();
  ASSERT_TRUE(leased);

  std::vector<IrradianceRecord> recs(5);
  for (int i = 0; i < 5; ++i) {
    recs[i].position = Vec3(0.1f * i, 0, 0);
    recs[i].normal = Vec3(0, 1, 0);
    recs[i].irradiance = Vec3(1, 1, 1);
    recs[i].radius = 0.5f;
  }
  recs[1].irradiance.x = std::nanf("");
  recs[3].normal = Vec3(0, 2, 0);
  v1::WorkerMessage batch;
  batch.mutable_records()->set_job_id(job_id);
  PackRecords(recs, 1, batch.mutable_records()->mutable_batch());
  ASSERT_TRUE(stream->Write(batch));
  v1::Job job;
  for (int i = 0; i < 100; ++i) {
    job = *manager_->GetJob(job_id);
    if (job.records_merged() + job.records_rejected() == 5) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(job.records_merged(), 3u);
  EXPECT_EQ(job.records_rejected(), 2u);
  stream->WritesDone();
  c.TryCancel();
  stream->Finish();
}

}  // namespace
}  // namespace irfarm

// A real irfarm Worker against a coordinator that sends it bad leases (a stand-in service over
// gRPC on loopback, in this process): a lease's rectangle comes over the network, and one that is
// empty, inverted, negative or past the film is answered with TileFailed naming it, without
// rendering and without ending the session; a good lease after them is rendered and reported.
// (A rectangle of width -16 reached the image allocation, whose length_error ended the process.)
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <limits>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "irfarm/v1/worker.grpc.pb.h"
#include "service/scene_bundle.h"
#include "worker/worker.h"

namespace irfarm {
namespace {

v1::PixelRect Rect(int x0, int y0, int x1, int y1) {
  v1::PixelRect r;
  r.set_x0(x0);
  r.set_y0(y0);
  r.set_x1(x1);
  r.set_y1(y1);
  return r;
}

using Stream = grpc::ServerReaderWriter<v1::CoordinatorMessage, v1::WorkerMessage>;

// A lease of tile `tile` of `job` over `rect`, its token 16 x `token`.
v1::CoordinatorMessage Lease(const std::string& job, int tile, const v1::PixelRect& rect,
                             char token) {
  v1::CoordinatorMessage out;
  v1::TileLease* l = out.mutable_lease();
  l->set_job_id(job);
  l->set_tile_index(tile);
  l->set_lease_token(std::string(16, token));
  *l->mutable_rect() = rect;
  return out;
}

// A stand-in coordinator's first steps: reads the worker's Register, registers it as worker 1
// and sends job "job-1", cornell-box at 32 x 32 rendered by path at `spp` in tiles of
// `tile_size` (0: the default, 32). False when the worker did not register.
bool RegisterAndSendJob(Stream* stream, int spp, int tile_size = 0) {
  v1::WorkerMessage in;
  if (!stream->Read(&in) || !in.has_register_()) return false;
  v1::CoordinatorMessage out;
  out.mutable_registered()->set_worker_id(1);
  out.mutable_registered()->set_heartbeat_ms(5000);
  stream->Write(out);
  out.Clear();
  v1::JobSpec* spec = out.mutable_job_spec();
  spec->set_job_id("job-1");
  *spec->mutable_scene()->mutable_bundle() =
      *MakeBundle(std::string(IRFARM_TEST_DATA) + "/scenes/cornell-box/scene.xml");
  (*spec->mutable_settings()->mutable_defines())["resx"] = "32";
  (*spec->mutable_settings()->mutable_defines())["resy"] = "32";
  spec->mutable_settings()->set_integrator("path");
  spec->mutable_settings()->set_spp(spp);
  spec->mutable_settings()->set_tile_size(tile_size);
  stream->Write(out);
  return true;
}

// Serves `service` on loopback, runs a real Worker (one thread, named `name`) against it until
// `done` or `seconds` passed, then stops both.
void RunWorkerAgainst(v1::WorkerService::Service* service, const std::string& name,
                      const std::atomic<bool>& done, int seconds) {
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  ASSERT_GT(port, 0);
  WorkerOptions options;
  options.coordinator = "127.0.0.1:" + std::to_string(port);
  options.name = name;
  options.threads = 1;
  Worker worker(options);
  std::thread run([&] { worker.Run(); });
  for (int i = 0; i < 20 * seconds && !done; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  worker.Stop();
  run.join();
  server->Shutdown(std::chrono::system_clock::now());
}

// Registers the worker, sends a 32 x 32 cornell-box job and `leases` in order (tile index = the
// lease's position), then reads until the worker answered every one; keeps what it answered.
class BadLeaseCoordinator final : public v1::WorkerService::Service {
 public:
  explicit BadLeaseCoordinator(std::vector<v1::PixelRect> leases) : leases_(std::move(leases)) {}

  grpc::Status Session(
      grpc::ServerContext*,
      grpc::ServerReaderWriter<v1::CoordinatorMessage, v1::WorkerMessage>* stream) override {
    if (!RegisterAndSendJob(stream, 4, 16)) return grpc::Status::CANCELLED;
    v1::WorkerMessage in;
    for (size_t i = 0; i < leases_.size(); ++i)
      stream->Write(Lease("job-1", int(i), leases_[i], char('a' + i)));
    size_t answered = 0;
    while (answered < leases_.size() && stream->Read(&in)) {
      std::lock_guard<std::mutex> lock(mu_);
      if (in.has_tile_failed()) {
        failed_.push_back({in.tile_failed().tile_index(), in.tile_failed().reason()});
        ++answered;
      } else if (in.has_tile_result()) {
        results_.push_back({in.tile_result().tile_index(), in.tile_result().pixels_size()});
        ++answered;
      }
    }
    done_ = true;
    return grpc::Status::OK;
  }

  std::vector<v1::PixelRect> leases_;
  std::mutex mu_;
  std::vector<std::pair<int, std::string>> failed_;
  std::vector<std::pair<int, int>> results_;
  std::atomic<bool> done_{false};
};

TEST(WorkerLeaseCheckTest, BadLeaseRectanglesFailTheTileAndTheSessionGoesOn) {
  // The job's tiles are 16 px: the whole 32 x 16 half of the film is inside it, but no tile.
  BadLeaseCoordinator service({Rect(0, 0, -16, 16), Rect(-16, -16, -32, -32), Rect(8, 0, 8, 16),
                               Rect(0, 0, 64, 16), Rect(0, 0, 2147483647, 16), Rect(0, 0, 32, 16),
                               Rect(0, 0, 16, 8)});
  RunWorkerAgainst(&service, "checker", service.done_, 30);
  ASSERT_TRUE(service.done_);
  std::lock_guard<std::mutex> lock(service.mu_);
  ASSERT_EQ(service.failed_.size(), 6u);
  for (size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(service.failed_[i].first, int(i));
    EXPECT_NE(service.failed_[i].second.find("lease rectangle"), std::string::npos)
        << service.failed_[i].second;
  }
  EXPECT_NE(service.failed_[0].second.find("outside the 32 x 32 film"), std::string::npos)
      << service.failed_[0].second;
  EXPECT_NE(service.failed_[5].second.find("larger than the job's 16 px tiles"), std::string::npos)
      << service.failed_[5].second;
  ASSERT_EQ(service.results_.size(), 1u);
  EXPECT_EQ(service.results_[0].first, 6);
  EXPECT_EQ(service.results_[0].second, 16 * 8 * 3);
}

// Registers the worker, sends a 32 x 32 cornell-box job of 65536 path samples a pixel (a tile
// of minutes on one thread) and its one tile, closes the job once the worker has started it
// (its TileRegion arrives just before the render), then leases another tile of the closed job:
// the worker answers that one (TileFailed: no job) as soon as its render loop is free.
class ClosingCoordinator final : public v1::WorkerService::Service {
 public:
  grpc::Status Session(
      grpc::ServerContext*,
      grpc::ServerReaderWriter<v1::CoordinatorMessage, v1::WorkerMessage>* stream) override {
    if (!RegisterAndSendJob(stream, 65536)) return grpc::Status::CANCELLED;
    v1::WorkerMessage in;
    v1::CoordinatorMessage out;
    const auto lease = [&](int tile) {
      stream->Write(Lease("job-1", tile, Rect(0, 0, 32, 32), char('a' + tile)));
    };
    lease(0);
    while (stream->Read(&in) && !in.has_tile_region()) {
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(300));  // into the render
    out.Clear();
    out.mutable_job_closed()->set_job_id("job-1");
    stream->Write(out);
    closed_at_ = std::chrono::steady_clock::now();
    lease(1);
    while (stream->Read(&in)) {
      std::lock_guard<std::mutex> lock(mu_);
      if (in.has_tile_result()) results_.push_back(in.tile_result().tile_index());
      if (in.has_tile_failed() && in.tile_failed().tile_index() == 0)
        stopped_reason_ = in.tile_failed().reason();
      if (in.has_tile_failed() && in.tile_failed().tile_index() == 1) {
        answered_after_ = std::chrono::steady_clock::now() - closed_at_;
        break;
      }
    }
    done_ = true;
    return grpc::Status::OK;
  }

  std::mutex mu_;
  std::vector<int> results_;
  std::string stopped_reason_;  // tile 0's TileFailed
  std::chrono::steady_clock::time_point closed_at_;
  std::chrono::steady_clock::duration answered_after_{};
  std::atomic<bool> done_{false};
};

// A tile whose job is closed while it renders (cancelled by its client, failed, or finished by
// other workers) stops rendering and is reported stopped (TileFailed, which a closed job does not
// count), not rendered to its end and sent: it held the worker for the whole tile before.
TEST(WorkerLeaseCheckTest, ATileOfAClosedJobStopsRendering) {
  ClosingCoordinator service;
  RunWorkerAgainst(&service, "closer", service.done_, 60);
  ASSERT_TRUE(service.done_) << "the worker never got to the second lease";
  std::lock_guard<std::mutex> lock(service.mu_);
  const double seconds = std::chrono::duration<double>(service.answered_after_).count();
  std::printf("MEASURED the worker answered the next lease %.3f s after the job closed\n", seconds);
  EXPECT_TRUE(service.results_.empty()) << "the closed job's tile was sent";
  // Its lease is given back (the coordinator holds a worker's lease until it hears of it).
  EXPECT_NE(service.stopped_reason_.find("stopped"), std::string::npos) << service.stopped_reason_;
  // The render checks its flag every 256 samples of a pixel: well under a second here, also under
  // ThreadSanitizer (a check at every row of 16 pixels of 65536 samples measured 5.05 s there in
  // CI); the whole tile takes minutes.
  EXPECT_LT(seconds, 5.0);
}

// Registers the worker, sends the 65536-sample job and leases its tile 0 for 1 s
// (TileLease::lease_ms), then reads until the worker reports the tile.
class DeadlineCoordinator final : public v1::WorkerService::Service {
 public:
  grpc::Status Session(grpc::ServerContext*, Stream* stream) override {
    if (!RegisterAndSendJob(stream, 65536)) return grpc::Status::CANCELLED;
    v1::CoordinatorMessage out = Lease("job-1", 0, Rect(0, 0, 32, 32), 'a');
    v1::TileLease* l = out.mutable_lease();
    l->set_lease_ms(1000);
    // A wall-clock deadline an hour back (a worker's clock far ahead of the coordinator's): the
    // worker goes by lease_ms on its own clock, not by it.
    const auto hour_ago = std::chrono::system_clock::now() - std::chrono::hours(1);
    l->set_deadline_unix_ms(
        std::chrono::duration_cast<std::chrono::milliseconds>(hour_ago.time_since_epoch()).count());
    stream->Write(out);
    const auto sent = std::chrono::steady_clock::now();
    v1::WorkerMessage in;
    while (stream->Read(&in)) {
      std::lock_guard<std::mutex> lock(mu_);
      if (in.has_tile_result()) results_.push_back(in.tile_result().tile_index());
      if (in.has_tile_failed()) {
        reason_ = in.tile_failed().reason();
        answered_after_ = std::chrono::steady_clock::now() - sent;
        break;
      }
    }
    done_ = true;
    return grpc::Status::OK;
  }

  std::mutex mu_;
  std::vector<int> results_;
  std::string reason_;
  std::chrono::steady_clock::duration answered_after_{};
  std::atomic<bool> done_{false};
};

// A tile still rendering at its lease's deadline stops and is reported (TileFailed): the
// coordinator has given it to another worker by then, and a worker that rendered on (or hung in
// the render) held a lease the coordinator waits on before it leases that worker again. The
// worker ignored the deadline before: this tile of minutes held it to its end.
TEST(WorkerLeaseCheckTest, ATilePastItsLeaseDeadlineStops) {
  DeadlineCoordinator service;
  RunWorkerAgainst(&service, "late", service.done_, 60);
  ASSERT_TRUE(service.done_) << "the worker never reported the tile";
  std::lock_guard<std::mutex> lock(service.mu_);
  const double seconds = std::chrono::duration<double>(service.answered_after_).count();
  std::printf("MEASURED the tile was reported %.3f s after its lease (deadline 1 s)\n", seconds);
  EXPECT_TRUE(service.results_.empty());
  EXPECT_NE(service.reason_.find("lease deadline passed"), std::string::npos) << service.reason_;
  EXPECT_GE(seconds, 0.95);  // not before the lease time (nor at once, by the wall clock)
  EXPECT_LT(seconds, 5.0);
}

// Registers the worker, sends 70 job specs whose scenes do not load ("j-0" ... "j-69"), then
// leases a tile of j-0 and one of j-69 and reads both answers.
class ManySpecsCoordinator final : public v1::WorkerService::Service {
 public:
  grpc::Status Session(grpc::ServerContext*, Stream* stream) override {
    v1::WorkerMessage in;
    if (!stream->Read(&in) || !in.has_register_()) return grpc::Status::CANCELLED;
    v1::CoordinatorMessage out;
    out.mutable_registered()->set_worker_id(1);
    out.mutable_registered()->set_heartbeat_ms(5000);
    stream->Write(out);
    for (int i = 0; i < 70; ++i) {
      out.Clear();
      v1::JobSpec* spec = out.mutable_job_spec();
      spec->set_job_id("j-" + std::to_string(i));
      v1::BundleFile* f = spec->mutable_scene()->mutable_bundle()->add_files();
      f->set_path("scene.xml");
      f->set_content("<scene version=\"3.0.0\"><shape type=\"nope\"/></scene>");
      stream->Write(out);
    }
    for (int i : {0, 69}) stream->Write(Lease("j-" + std::to_string(i), i, Rect(0, 0, 8, 8), 'a'));
    while (reasons_.size() < 2 && stream->Read(&in)) {
      std::lock_guard<std::mutex> lock(mu_);
      if (in.has_tile_failed()) reasons_[in.tile_failed().tile_index()] = in.tile_failed().reason();
    }
    done_ = true;
    return grpc::Status::OK;
  }

  std::mutex mu_;
  std::map<int, std::string> reasons_;  // tile index (the job's number) -> why it failed
  std::atomic<bool> done_{false};
};

// A session holds at most 64 jobs for its coordinator (loaded or failed, each until its
// JobClosed): a coordinator sending spec after spec grew the worker's memory and temp dirs
// without end. The 65th and later are ignored, and their leases fail for want of a spec.
TEST(WorkerLeaseCheckTest, ASessionHoldsAtMost64Jobs) {
  ManySpecsCoordinator service;
  RunWorkerAgainst(&service, "many", service.done_, 60);
  ASSERT_TRUE(service.done_);
  std::lock_guard<std::mutex> lock(service.mu_);
  EXPECT_NE(service.reasons_[0].find("nope"), std::string::npos) << service.reasons_[0];
  EXPECT_EQ(service.reasons_[69], "job spec not received");
}

// Sends leases whose token (1 MiB) or job id (1000 bytes) no coordinator makes, a job spec with a
// 1 MiB id, then a good lease (tile 2, lease_ms the largest int64); reads until the good one is
// answered, keeping every answer.
class OversizedIdsCoordinator final : public v1::WorkerService::Service {
 public:
  grpc::Status Session(grpc::ServerContext*, Stream* stream) override {
    if (!RegisterAndSendJob(stream, 4, 16)) return grpc::Status::CANCELLED;
    v1::CoordinatorMessage big_token = Lease("job-1", 0, Rect(0, 0, 16, 16), 'a');
    big_token.mutable_lease()->set_lease_token(std::string(size_t(1) << 20, 't'));
    stream->Write(big_token);
    stream->Write(Lease(std::string(1000, 'j'), 1, Rect(0, 0, 16, 16), 'b'));
    v1::CoordinatorMessage spec;
    spec.mutable_job_spec()->set_job_id(std::string(size_t(1) << 20, 'k'));
    stream->Write(spec);
    // The good lease's time beyond any clock (steady_clock's nanoseconds overflowed): rendered.
    v1::CoordinatorMessage good = Lease("job-1", 2, Rect(0, 0, 16, 16), 'c');
    good.mutable_lease()->set_lease_ms(std::numeric_limits<int64_t>::max());
    stream->Write(good);
    v1::WorkerMessage in;
    while (!done_ && stream->Read(&in)) {
      std::lock_guard<std::mutex> lock(mu_);
      if (in.has_tile_failed()) {
        answered_.push_back(in.tile_failed().tile_index());
        longest_ = std::max(
            longest_, in.tile_failed().lease_token().size() + in.tile_failed().job_id().size());
      } else if (in.has_tile_result()) {
        answered_.push_back(in.tile_result().tile_index());
        longest_ = std::max(
            longest_, in.tile_result().lease_token().size() + in.tile_result().job_id().size());
        if (in.tile_result().tile_index() == 2) done_ = true;
      }
    }
    return grpc::Status::OK;
  }

  std::mutex mu_;
  std::vector<int> answered_;
  size_t longest_ = 0;
  std::atomic<bool> done_{false};
};

// Ids and tokens longer than 64 bytes are dropped on arrival (a review: a lease's 200 MB token was
// queued whole, 256 deep, logged and echoed back); the session goes on and renders a good lease.
TEST(WorkerLeaseCheckTest, OversizedIdsAndTokensAreDropped) {
  OversizedIdsCoordinator service;
  RunWorkerAgainst(&service, "sizes", service.done_, 60);
  ASSERT_TRUE(service.done_) << "the good lease was not rendered";
  std::lock_guard<std::mutex> lock(service.mu_);
  EXPECT_EQ(service.answered_, std::vector<int>{2});
  EXPECT_LE(service.longest_, 64u);
}

}  // namespace
}  // namespace irfarm

// SimWorker: one simulated irfarm worker of the scale simulation (scale_sim.cc), speaking the real
// worker protocol (proto/irfarm/v1/worker.proto) on its own gRPC channel and TCP connection:
// registers with reports_regions, takes job specs and leases, reports each lease's TileRegion
// (the real worker/tile_region.h box of the tile, computed once per tile and shared by all
// simulated workers), "renders" the tile by publishing synthetic records for a drawn tile time
// and returns a valid TileResult; receives the records fanned out to it and measures their
// delivery latency from the send time tagged into each record (record_tag.h), and the lease
// latency (tile result written to next lease received).
//
// Synthetic records are drawn like a real worker's: at the first hits of random camera rays
// through the leased tile (a pool per tile), a fraction `far_fraction` anywhere the camera sees
// (a pool over the whole image: records made for indirect rays), with the tile's normal, a radius
// whose reach a * R covers 1.5 to 16 pixel footprints (the irrcache defaults' clamp) and
// irradiance within the scene's bound. Records are published every flush_interval (the real
// worker's 50 ms), so each message carries rate * interval records.
//
// Threads: Run's thread writes (register, regions, records, results, heartbeats); a reader
// thread reads. Stats are the worker's own until Join returns; the measurement window is shared
// (MeasureWindow) and only read.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "bench/latency_histogram.h"
#include "bench/record_tag.h"
#include "cache/irradiance_record.h"
#include "render/record_bounds.h"
#include "core/math.h"
#include "irfarm/v1/worker.grpc.pb.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace irfarm {

// Microseconds of the steady clock, modulo 2^32 (the clock of record tags).
inline uint32_t NowUs32() {
  return uint32_t(std::chrono::duration_cast<std::chrono::microseconds>(
                      std::chrono::steady_clock::now().time_since_epoch())
                      .count());
}

// A surface point a record can sit at: first hit of a camera ray.
struct SimHit {
  Vec3 p, n;        // n: unit, facing the camera
  float footprint;  // one pixel's width at the hit (scene units)
};

// What the simulated workers share about the job's scene (built once, read-only after
// PrepareImagePool; TileInfo fills lazily, thread-safe).
class SimScene {
 public:
  // `scene`: loaded with the job's defines (same camera as the job); `tile_size` the job's.
  SimScene(const Scene* scene, const RecordBounds& bounds, float accuracy, int tile_size);

  struct Tile {
    std::once_flag once;
    std::optional<Bounds3> region;  // TileRegionOf (nullopt: the tile sees nothing)
    std::vector<SimHit> hits;       // first hits of random rays through the tile
  };
  // The tile `index` of the job (rect as leased); null for an index outside the film's tiles.
  const Tile* TileInfo(int index, const PixelRect& rect);
  // Fills every tile's region and hits now, on `threads` threads (so that the simulation's
  // measured runs do not trace TileRegionOf's rays: a real worker would, on its own machine).
  void PrepareAll(int threads);
  const std::vector<SimHit>& image_hits() const { return image_hits_; }
  const RecordBounds& bounds() const { return bounds_; }
  float accuracy() const { return accuracy_; }

 private:
  const Scene* scene_;
  int tile_size_;
  RecordBounds bounds_;
  float accuracy_;
  std::vector<std::unique_ptr<Tile>> tiles_;
  std::vector<SimHit> image_hits_;
};

// The measurement window, in NowUs32 time. Bytes and leases count while it is open; a record
// counts in the latency figures when it was sent inside [start_us, end_us), whenever it arrives
// (the bench waits a grace period after closing the window, so that slow records count too).
struct MeasureWindow {
  std::atomic<int> state{0};  // 0: not started, 1: open, 2: closed
  std::atomic<uint32_t> start_us{0}, end_us{0};

  bool open() const { return state.load(std::memory_order_relaxed) == 1; }
  // Whether a record sent at `send_us` was sent inside the window (as far as is known now).
  bool SentInside(uint32_t send_us) const {
    const int s = state.load(std::memory_order_acquire);
    if (s == 0 || int32_t(send_us - start_us.load(std::memory_order_relaxed)) < 0) return false;
    return s == 1 || int32_t(end_us.load(std::memory_order_relaxed) - send_us) > 0;
  }
};

struct SimWorkerOptions {
  std::string coordinator;
  uint32_t index = 0;                // in record tags and the name "sim-<index>"
  double records_per_second = 2000;  // published while holding a lease
  std::chrono::milliseconds flush_interval{50};
  double tile_seconds = 1.0;  // mean; each tile draws uniformly in [0.5, 1.5] x
  double far_fraction = 0.1;  // records anywhere the camera sees
  bool keep_records = false;  // keep every record published and received (smoke)
  bool filtered = true;       // the coordinator runs --fanout=region
  SimScene* scene = nullptr;
  const MeasureWindow* window = nullptr;
};

struct SimWorkerStats {
  uint32_t worker_id = 0;  // from the coordinator; 0 = never registered
  std::string error;       // why the session ended early, if it did
  uint64_t tiles = 0, records_sent = 0, rejected = 0;
  std::string last_rejection;
  // Fan-out received: live (forwarded as it arrived at the coordinator) and late (held back
  // until this worker joined the job or its region grew to meet the record: late join and
  // backlog). A record counts as late when it was sent before this worker joined, or does not
  // reach the union of the regions it had reported when the record was sent (the coordinator
  // filtered it against that union). Only live records count in the latency figures.
  uint64_t records_live = 0, records_late = 0;
  // Inside the window: bytes of the messages written and read, records sent and received live.
  uint64_t window_bytes_sent = 0, window_bytes_received = 0;
  uint64_t window_records_sent = 0, window_records_received = 0;
  LatencyHistogram record_latency;  // live records sent inside the window
  LatencyHistogram lease_latency;   // tile result written -> next lease read, inside the window
  bool job_closed = false;          // a JobClosed arrived
  // keep_records only: the records as published (tags included), the ids of those received,
  // and the regions reported (job-clipped by the coordinator, not here).
  std::vector<IrradianceRecord> published;
  std::vector<uint64_t> received_ids;
  std::vector<v1::TileRegion> regions;
};

class SimWorker {
 public:
  explicit SimWorker(SimWorkerOptions options) : options_(std::move(options)) {}
  ~SimWorker() { Join(); }
  void Start();
  // Ends the session at the next step (a tile in progress is abandoned, like a killed worker).
  void Stop() { stop_ = true; }
  void Join() {
    if (thread_.joinable()) thread_.join();
  }
  bool registered() const { return registered_.load(); }
  bool job_closed() const { return job_closed_.load(); }
  // Valid after Join.
  const SimWorkerStats& stats() const { return stats_; }

 private:
  void Run();
  // Reader thread: everything the coordinator sends.
  void Read(grpc::ClientReaderWriter<v1::WorkerMessage, v1::CoordinatorMessage>* stream);
  void ReceiveRecords(const v1::RecordBatch& batch, uint32_t now_us);
  // Whether a record sent at `send_us` reached this worker by live fan-out (see records_late).
  bool Live(const float* packed, uint32_t send_us);
  // Draws `n` records around `tile` into records_ (tagged at send time by the caller).
  void DrawRecords(size_t n, const SimScene::Tile* tile);
  uint64_t NextRandom();
  float Uniform() { return float(NextRandom() >> 40) * (1.0f / 16777216.0f); }

  SimWorkerOptions options_;
  std::thread thread_;
  std::atomic<bool> stop_{false}, registered_{false}, job_closed_{false};
  SimWorkerStats stats_;  // written by both threads, on disjoint fields (see Read)
  uint64_t rng_ = 0;
  uint32_t sequence_ = 0;
  std::vector<IrradianceRecord> records_;
  std::atomic<uint32_t> result_sent_us_{0};
  std::atomic<bool> awaiting_lease_{false};  // a result was written, its next lease not read
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<v1::TileLease> leases_;
  std::string job_id_;  // of the last JobSpec
  bool broken_ = false;
  // The union of the regions reported so far, after each report (first entry: the job spec's
  // arrival with an empty box, or an everything box unfiltered), and when; guarded by mu_.
  struct RegionStep {
    uint32_t at_us;
    Bounds3 box;
  };
  std::vector<RegionStep> region_steps_;
  std::atomic<uint32_t> last_step_us_{0};
  std::atomic<bool> has_steps_{false};
};

}  // namespace irfarm

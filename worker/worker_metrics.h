// WorkerMetrics: one worker process's Prometheus metrics (service/metrics.h), updated by Worker
// and served by `irfarm-worker --metrics ADDR` at GET /metrics: tiles, records computed, sent and
// received (count and bytes), irradiance-cache lookups and hits (and their ratio), rays by kind,
// tile render time and stream write latency, connection state.
#pragma once

#include "service/metrics.h"

namespace irfarm {

struct WorkerMetrics {
  explicit WorkerMetrics(MetricsRegistry* registry);

  Counter* tiles_completed;
  Counter* tiles_failed;     // TileFailed sent (the job's scene did not load here)
  Counter* tiles_cancelled;  // renders stopped: the job was closed or the session broke
  Counter* records_computed;
  Counter* records_sent;
  Counter* record_bytes_sent;
  Counter* records_received;
  Counter* record_bytes_received;
  Counter* lookups;
  Counter* lookup_hits;
  Counter* camera_rays;
  Counter* bounce_rays;
  Counter* shadow_rays;
  Counter* record_rays;
  Counter* sessions;         // sessions registered (1 + reconnects)
  Gauge* connected;          // 1 while a session is registered
  Histogram* tile_seconds;   // wall time of one tile (overture + render)
  Histogram* write_seconds;  // one message written on the session stream
};

}  // namespace irfarm

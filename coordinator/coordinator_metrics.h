// CoordinatorMetrics: the coordinator's Prometheus metrics (service/metrics.h), registered once
// and updated where the events happen (JobManager, the gRPC services, TimedJobStore). Values that
// are a view of the current state (jobs by state, per-job progress, connected workers) are
// written at scrape time by JobManager's collector instead. Exported by `irfarm-coordinator
// --metrics ADDR` at GET /metrics.
#pragma once

#include "service/metrics.h"

namespace irfarm {

struct CoordinatorMetrics {
  explicit CoordinatorMetrics(MetricsRegistry* registry);

  Counter* jobs_submitted;
  Counter* tiles_completed;
  Counter* tiles_failed;            // TileFailed messages and invalid tile results
  Counter* lease_expired_deadline;  // leases requeued at their deadline
  Counter* lease_expired_silent;    // leases taken from a worker silent for 3 heartbeats
  Counter* lease_lost_disconnect;   // leases requeued because the worker's stream ended
  Counter* records_received;        // records workers published (before validation)
  Counter* record_bytes_received;
  Counter* records_merged;    // accepted into a job's global cache
  Counter* records_rejected;  // refused by validation
  Counter* records_sent;      // records streamed to workers (fan-out and late join)
  Counter* record_bytes_sent;
  Counter* fanout_batches_dropped;  // a worker's outbox was full
  Counter* records_withheld;        // not sent: outside the worker's region (filtered fan-out)
  Counter* records_backlog;         // sent late, when a worker's region grew to reach them
  Counter* regions_accepted;        // TileRegion messages that grew a worker's region or not
  Counter* regions_rejected;        // malformed TileRegion messages (violations)
  Counter* worker_violations;
  Counter* records_computed;  // summed from workers' tile stats
  Counter* lookups;           // irradiance-cache queries, from workers' tile stats
  Counter* lookup_hits;
  Counter* jobs_expired;  // finished jobs removed by retention (TTL or count)
  Counter* jobs_deleted;  // removed by DeleteJob
};

}  // namespace irfarm

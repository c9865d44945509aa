// CoordinatorMetrics: names and help texts (see coordinator_metrics.h).
#include "coordinator/coordinator_metrics.h"

namespace irfarm {

CoordinatorMetrics::CoordinatorMetrics(MetricsRegistry* r)
    : jobs_submitted(r->AddCounter("irfarm_jobs_submitted_total", "Jobs accepted by SubmitJob.")),
      tiles_completed(
          r->AddCounter("irfarm_tiles_completed_total", "Tile results accepted (all jobs).")),
      tiles_failed(r->AddCounter("irfarm_tiles_failed_total",
                                 "Tiles reported failed or sent back invalid by a worker.")),
      lease_expired_deadline(r->AddCounter("irfarm_lease_expiries_total",
                                           "Tile leases taken back from a worker.",
                                           {{"reason", "deadline"}})),
      lease_expired_silent(
          r->AddCounter("irfarm_lease_expiries_total", "", {{"reason", "silent_worker"}})),
      lease_lost_disconnect(
          r->AddCounter("irfarm_lease_expiries_total", "", {{"reason", "disconnected"}})),
      records_received(r->AddCounter("irfarm_records_received_total",
                                     "Irradiance records published by workers.")),
      record_bytes_received(r->AddCounter("irfarm_record_bytes_received_total",
                                          "Record payload bytes published by workers.")),
      records_merged(r->AddCounter("irfarm_records_merged_total",
                                   "Records accepted into a job's global cache.")),
      records_rejected(r->AddCounter("irfarm_records_rejected_total",
                                     "Records refused by validation (bounds, finiteness).")),
      records_sent(r->AddCounter("irfarm_records_sent_total",
                                 "Records streamed to workers (fan-out and late join).")),
      record_bytes_sent(r->AddCounter("irfarm_record_bytes_sent_total",
                                      "Record payload bytes streamed to workers.")),
      fanout_batches_dropped(
          r->AddCounter("irfarm_fanout_batches_dropped_total",
                        "Record batches not queued for a worker because its outbox was full.")),
      records_withheld(r->AddCounter(
          "irfarm_records_withheld_total",
          "Records not sent to a worker: they reach no tile region of it (filtered fan-out).")),
      records_backlog(r->AddCounter(
          "irfarm_records_backlog_total",
          "Withheld records sent later, when the worker's region grew to reach them.")),
      regions_accepted(
          r->AddCounter("irfarm_tile_regions_total", "TileRegion messages accepted from workers.")),
      regions_rejected(r->AddCounter("irfarm_tile_regions_rejected_total",
                                     "Malformed TileRegion messages (counted as violations).")),
      worker_violations(r->AddCounter("irfarm_worker_violations_total",
                                      "Invalid messages from workers (answered Rejected).")),
      records_computed(r->AddCounter("irfarm_records_computed_total",
                                     "Records workers computed, from their tile stats.")),
      lookups(r->AddCounter("irfarm_cache_lookups_total",
                            "Irradiance-cache queries, from workers' tile stats.")),
      lookup_hits(r->AddCounter("irfarm_cache_lookup_hits_total",
                                "Irradiance-cache queries answered by interpolation.")),
      jobs_expired(r->AddCounter("irfarm_jobs_expired_total",
                                 "Finished jobs removed by retention (TTL or count).")),
      jobs_deleted(r->AddCounter("irfarm_jobs_deleted_total", "Jobs removed by DeleteJob.")) {}

}  // namespace irfarm

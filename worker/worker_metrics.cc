// WorkerMetrics: names and help texts (see worker_metrics.h).
#include "worker/worker_metrics.h"

#include <limits>

namespace irfarm {

WorkerMetrics::WorkerMetrics(MetricsRegistry* r)
    : tiles_completed(r->AddCounter("irfarm_worker_tiles_completed_total",
                                    "Tiles rendered and sent to the coordinator.")),
      tiles_failed(r->AddCounter("irfarm_worker_tiles_failed_total",
                                 "Tiles reported failed (the job's scene did not load).")),
      tiles_cancelled(r->AddCounter(
          "irfarm_worker_tiles_cancelled_total",
          "Tile renders stopped before the end: their job was closed or the session broke.")),
      records_computed(r->AddCounter("irfarm_worker_records_computed_total",
                                     "Irradiance records computed by this worker.")),
      records_sent(r->AddCounter("irfarm_worker_records_sent_total",
                                 "Records published to the coordinator.")),
      record_bytes_sent(r->AddCounter("irfarm_worker_record_bytes_sent_total",
                                      "Record payload bytes published.")),
      records_received(r->AddCounter("irfarm_worker_records_received_total",
                                     "Records of other workers (and imported) received.")),
      record_bytes_received(r->AddCounter("irfarm_worker_record_bytes_received_total",
                                          "Record payload bytes received.")),
      lookups(r->AddCounter("irfarm_worker_cache_lookups_total", "Irradiance-cache queries.")),
      lookup_hits(r->AddCounter("irfarm_worker_cache_lookup_hits_total",
                                "Irradiance-cache queries answered by interpolation.")),
      camera_rays(
          r->AddCounter("irfarm_worker_rays_total", "Rays traced, by kind.", {{"kind", "camera"}})),
      bounce_rays(r->AddCounter("irfarm_worker_rays_total", "", {{"kind", "bounce"}})),
      shadow_rays(r->AddCounter("irfarm_worker_rays_total", "", {{"kind", "shadow"}})),
      record_rays(r->AddCounter("irfarm_worker_rays_total", "", {{"kind", "record"}})),
      sessions(r->AddCounter("irfarm_worker_sessions_total",
                             "Sessions registered with the coordinator (1 + reconnects).")),
      connected(r->AddGauge("irfarm_worker_connected", "1 while registered with a coordinator.")),
      tile_seconds(r->AddHistogram("irfarm_worker_tile_duration_seconds",
                                   "Wall time to render one tile (overture and final pass).",
                                   LatencyBuckets())),
      write_seconds(r->AddHistogram("irfarm_worker_rpc_duration_seconds",
                                    "Time to write one message on the session stream.",
                                    LatencyBuckets(), {{"method", "Session/write"}})) {
  r->AddCollector([lookups = lookups, hits = lookup_hits](MetricsWriter& w) {
    const double n = double(lookups->value());
    w.Family("irfarm_worker_cache_hit_ratio", "gauge",
             "Irradiance-cache queries answered by interpolation / all queries (NaN before any).");
    w.Sample("irfarm_worker_cache_hit_ratio", {},
             n > 0 ? double(hits->value()) / n : std::numeric_limits<double>::quiet_NaN());
  });
}

}  // namespace irfarm

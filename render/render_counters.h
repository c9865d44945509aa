// Per-thread work counters of a render; summed into the stats JSON at the end. Each thread owns
// one (tbb::enumerable_thread_specific), so counting costs no atomics on the hot path.
#pragma once

#include <cstdint>

namespace irfarm {

struct RenderCounters {
  uint64_t camera_rays = 0;        // primary rays
  uint64_t bounce_rays = 0;        // BSDF-sampled continuation rays (incl. specular)
  uint64_t shadow_rays = 0;        // next-event-estimation visibility rays
  uint64_t nonfinite_samples = 0;  // samples (or light-sample terms) that were NaN or infinite
  uint64_t lights_skipped = 0;     // lights that could not reach a shading point: no shadow ray
  uint64_t record_rays = 0;        // first rays of irradiance-record hemispheres
  uint64_t glossy_bounces = 0;     // irrcache camera-path vertices shaded through a glossy lobe
  uint64_t records_computed = 0;
  uint64_t records_secondary = 0;  // of records_computed, level 1 or deeper (IrradianceRecord)
  // Of records_secondary, those with one ray bringing more than kHeavyRayShare of the record's
  // sum (render/record_balance.h: what decides a third cache level).
  uint64_t records_secondary_heavy = 0;
  uint64_t records_hessian = 0;      // of records_computed, spaced by their Hessian
  uint64_t lookups = 0;              // irradiance-cache queries
  uint64_t lookup_hits = 0;          // queries answered by interpolation
  uint64_t region_lookups = 0;       // of lookups, answered from a pixel's gathered region
  uint64_t records_used = 0;         // records summed over successful queries
  uint64_t remote_records_used = 0;  // of records_used, those computed by another process
  double record_seconds = 0;         // thread time spent computing records
  uint64_t record_work = 0;          // of Work(), what computing records took
  // Records being computed on this thread right now (a record's rays can make others): only the
  // outermost one adds its time to record_seconds. Not summed.
  int record_nesting = 0;

  // Rays traced and cache queries: the work a render did, counted, not timed (a time measured on a
  // shared machine moves with the other processes' load; these are the same on any machine).
  uint64_t Work() const { return camera_rays + bounce_rays + shadow_rays + record_rays + lookups; }

  void Add(const RenderCounters& o) {
    camera_rays += o.camera_rays;
    bounce_rays += o.bounce_rays;
    shadow_rays += o.shadow_rays;
    lights_skipped += o.lights_skipped;
    nonfinite_samples += o.nonfinite_samples;
    record_rays += o.record_rays;
    glossy_bounces += o.glossy_bounces;
    records_computed += o.records_computed;
    records_secondary += o.records_secondary;
    records_secondary_heavy += o.records_secondary_heavy;
    records_hessian += o.records_hessian;
    lookups += o.lookups;
    lookup_hits += o.lookup_hits;
    region_lookups += o.region_lookups;
    records_used += o.records_used;
    remote_records_used += o.remote_records_used;
    record_seconds += o.record_seconds;
    record_work += o.record_work;
  }
};

}  // namespace irfarm

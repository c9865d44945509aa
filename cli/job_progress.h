// Job progress for `irfarm status`, `irfarm watch` and `irfarm submit --wait`: the fraction of
// tiles done, the tile rate so far and the time left at that rate (ETA), and one-line text with
// a bar. The rate is tiles done / seconds since the job's first lease (Job.elapsed_seconds); a
// job resumed after a coordinator restart counts its earlier tiles in a shorter time, so its
// first estimates are optimistic.
#pragma once

#include <string>

#include "irfarm/v1/jobs.pb.h"

namespace irfarm {

struct JobProgress {
  double fraction = 0;          // tiles done / tiles, 0..1
  double tiles_per_second = 0;  // 0 until a tile is done
  double eta_seconds = -1;      // time left at that rate; < 0: unknown (nothing done yet)
};

JobProgress ProgressOf(const v1::Job& job);

// "RUNNING" for JOB_STATE_RUNNING; a state this build does not know (a newer coordinator's)
// has no name: "STATE_7".
std::string StateName(v1::JobState state);

// "45s", "3m05s", "2h07m"; "?" for a negative time.
std::string FormatDuration(double seconds);

// "job-3      RUNNING   [#########.........]  45%  29/64 tiles  3.1 tiles/s  ETA 11s  records
// 1234" (final jobs show the time they took instead of rate and ETA).
std::string ProgressLine(const v1::Job& job, int bar_width = 30);

}  // namespace irfarm

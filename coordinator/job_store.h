// JobStore: where the coordinator keeps what must survive it: each job (its public state, scene
// and settings), its finished tiles' pixels and its merged records. JobManager writes through to
// the store and reads it all back at start-up to resume unfinished jobs. Two implementations
// share one test suite: InMemoryJobStore (the default; nothing survives the process) and
// RedisJobStore (survives a coordinator restart).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/cord.h"
#include "cache/irradiance_record.h"
#include "irfarm/v1/store.pb.h"

namespace irfarm {

class JobStore {
 public:
  virtual ~JobStore() = default;

  // A new job number, unique for the life of the store (1, 2, ...).
  virtual absl::StatusOr<uint64_t> NextJobNumber() = 0;
  // Creates or replaces the job stored under job.job().id(). Its scene is written only when
  // `job` has one (the submit; a finished job's emptied bundle): a state change passes the job
  // without its scene (JobManager's StateOnly) and the scene stored before stays, so the upload
  // (up to --max-upload-mib) is not copied and written again each time a job starts or changes
  // priority. A state change of an unfinished job whose scene the store does not hold writes
  // nothing and fails IsSceneMissing.
  virtual absl::Status PutJob(const v1::StoredJob& job) = 0;
  // Every stored job with its scene, in no particular order (a job whose scene is lost comes
  // without one).
  virtual absl::StatusOr<std::vector<v1::StoredJob>> LoadJobs() = 0;

  // A finished tile's bytes (its float RGB pixels, then the guides and the firefly peaks where the
  // job has them: JobManager::Job::pixels). Idempotent per tile. Tiles and
  // records of a job the store does not hold (never put, or deleted) are refused NOT_FOUND.
  virtual absl::Status PutTile(const std::string& job_id, int tile, const std::string& pixels) = 0;
  virtual absl::StatusOr<std::map<int, std::string>> LoadTiles(const std::string& job_id) = 0;

  // Appends merged (already validated) records; LoadRecords returns them all in order. Readers
  // validate them again (design: every record read back is validated before use).
  virtual absl::Status AppendRecords(const std::string& job_id,
                                     const std::vector<IrradianceRecord>& records) = 0;
  virtual absl::StatusOr<std::vector<IrradianceRecord>> LoadRecords(const std::string& job_id) = 0;

  // Removes the job, its tiles and its records (retention, DeleteJob). OK when it is not there.
  // RedisJobStore also refuses (NOT_FOUND) a later PutJob of that id for a day: a write sent
  // before the delete may land after it.
  virtual absl::Status DeleteJob(const std::string& job_id) = 0;
};

// Whether a job in state `s` is finished (succeeded, failed or cancelled): it needs its scene no
// more.
inline bool IsFinalState(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
}

// What a state-only PutJob (an unfinished job without its scene) returns when the store holds no
// scene for the job: it lost it (Redis flushed, or the scene's key evicted) or never had it.
// FAILED_PRECONDITION marked with a payload; the caller writes the job again with its scene
// (StoreWriter does, with the scene JobManager still holds). A finished job's state is written
// without one.
inline constexpr char kSceneMissingPayload[] = "irfarm.dev/job-store/scene-missing";
inline absl::Status SceneMissingError(const std::string& message) {
  absl::Status st = absl::FailedPreconditionError(message);
  st.SetPayload(kSceneMissingPayload, absl::Cord("1"));
  return st;
}
inline bool IsSceneMissing(const absl::Status& st) {
  return st.GetPayload(kSceneMissingPayload).has_value();
}

// `stored` = `job`, but keeping the scene `stored` has when `job` has none (a state change, as
// JobStore::PutJob stores it).
inline void ReplaceKeepingScene(v1::StoredJob& stored, const v1::StoredJob& job) {
  if (job.has_scene() || !stored.has_scene()) {
    stored = job;
    return;
  }
  v1::SceneSource scene;
  scene.Swap(stored.mutable_scene());
  stored = job;
  stored.mutable_scene()->Swap(&scene);
}

// A copy of `stored` without its scene, for a state change's PutJob. The scene is swapped out and
// back (so the upload is not copied: this runs under JobManager's lock); `stored` is unchanged.
inline v1::StoredJob StateOnly(v1::StoredJob& stored) {
  if (!stored.has_scene()) return stored;
  v1::SceneSource scene;
  scene.Swap(stored.mutable_scene());
  v1::StoredJob state = stored;
  state.clear_scene();
  stored.mutable_scene()->Swap(&scene);
  return state;
}

}  // namespace irfarm

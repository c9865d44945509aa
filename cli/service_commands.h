// The `irfarm` subcommands that talk to a coordinator: submit, status, watch, cancel, delete,
// fetch, snapshot.
// Each returns the process exit code (0 ok, 1 failed, 2 bad usage) and prints errors as
// "error: CODE: message" on stderr. Every call carries the client's token and goes over TLS when
// asked (service/client_auth.h). The address may be a comma-separated list (an active
// coordinator and its standbys): a command uses the one accepting connections, and `watch` and
// `submit --wait` follow the job on to the coordinator that takes over when it dies.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "service/client_auth.h"

namespace irfarm {

// --coordinator, else $IRFARM_COORDINATOR, else 127.0.0.1:50051.
std::string DefaultCoordinator();

// Where the coordinator is and how to authenticate to it.
struct ServiceConnection {
  std::string address;  // HOST:PORT, or HOST:PORT,HOST:PORT,... (service/coordinator_list.h)
  ClientAuthOptions auth;
};

struct SubmitArgs {
  ServiceConnection coordinator;
  std::vector<std::string> scenes;
  int priority = 50;
  bool wait = false, quiet = false;
  std::string output, cache_in;
  std::string integrator;
  int spp = 0, record_rays = 0, tile_size = 0;
  float accuracy = 0;
  uint64_t seed = 0;
  bool no_share = false, shared_path = false, no_overture = false, no_caustics = false;
  bool no_firefly_filter = false;
  bool denoise = false;                          // the coordinator denoises the assembled image
  double target_error = 0, tile_time_limit = 0;  // adaptive sampling towards an error, per tile
  std::vector<std::string> defines;
};

int RunSubmit(const SubmitArgs& args);
// With `workers`: the connected workers (quarantine, violations) and the security counters.
int RunStatus(const ServiceConnection& coordinator, const std::string& job_id, bool json,
              bool workers = false);
int RunCancel(const ServiceConnection& coordinator, const std::string& job_id);
// Removes a finished job (image, tiles, records) from the coordinator and its store.
int RunDelete(const ServiceConnection& coordinator, const std::string& job_id);
// Follows a job with a live progress bar (rate, ETA) until it ends; 0 when it succeeded. On a
// terminal the line is redrawn in place; otherwise a line is printed at most once a second and
// at the end.
int RunWatch(const ServiceConnection& coordinator, const std::string& job_id);
int RunFetch(const ServiceConnection& coordinator, const std::string& job_id,
             const std::string& output);
int RunSnapshot(const ServiceConnection& coordinator, const std::string& job_id,
                const std::string& output);

}  // namespace irfarm

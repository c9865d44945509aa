// Client side of the job API for the `irfarm` command (see service_commands.h).
#include "cli/service_commands.h"

#include <fcntl.h>
#include <google/protobuf/util/json_util.h>
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>

#include "cache/snapshot.h"
#include "cli/job_progress.h"
#include "cli/paths.h"
#include "irfarm/v1/jobs.grpc.pb.h"
#include "service/coordinator_list.h"
#include "service/scene_bundle.h"

namespace irfarm {
namespace {

constexpr int kRpcSeconds = 60;  // deadline of unary calls
// Given several coordinator addresses: how long to look for the one accepting connections (a
// standby takes over within ~4 s of the active one's death, irfarm-coordinator --ha), and how
// many times a broken WatchJob stream is followed again on the next active one.
constexpr int kFindSeconds = 10;
constexpr int kMaxFailovers = 10;

// A stub and the token its calls carry.
struct Client {
  std::unique_ptr<v1::JobService::Stub> stub;
  std::string token;
  absl::Status status;  // why there is no stub
};

Client Connect(const ServiceConnection& c) {
  Client client;
  absl::StatusOr<std::string> token = LoadClientToken(c.auth);
  absl::StatusOr<std::shared_ptr<grpc::ChannelCredentials>> creds = MakeChannelCredentials(c.auth);
  if (!token.ok() || !creds.ok()) {
    client.status = !token.ok() ? token.status() : creds.status();
    return client;
  }
  client.token = *token;
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(-1);
  args.SetMaxSendMessageSize(-1);
  absl::StatusOr<std::vector<std::string>> addresses = CoordinatorList::Parse(c.address);
  if (!addresses.ok()) {
    client.status = addresses.status();
    return client;
  }
  if (addresses->size() == 1) {
    client.stub = v1::JobService::NewStub(grpc::CreateCustomChannel(c.address, *creds, args));
    return client;
  }
  // A coordinator that starts listening while we look is seen within 1 s.
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 100);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 1000);
  CoordinatorList list(*addresses, *creds, args);
  std::optional<size_t> i =
      list.FindConnected(std::chrono::system_clock::now() + std::chrono::seconds(kFindSeconds));
  if (!i) {
    client.status = absl::UnavailableError("no coordinator of " + list.ToString() +
                                           " accepts connections (waited " +
                                           std::to_string(kFindSeconds) + " s)");
    return client;
  }
  client.stub = v1::JobService::NewStub(list.channel(*i));
  return client;
}

bool IsFinal(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
}

// Follows a job (WatchJob), handing each update to `on_update`, until the stream ends. Given
// several coordinator addresses, a stream that broke before the job ended (UNAVAILABLE, or
// CANCELLED by a coordinator shutting down) is followed again on the coordinator that accepts
// connections next (a standby that took over), up to kMaxFailovers times.
grpc::Status FollowJob(const ServiceConnection& c, Client* client, const std::string& job_id,
                       const std::function<void(const v1::Job&)>& on_update) {
  const bool several = c.address.find(',') != std::string::npos;
  for (int failovers = 0;; ++failovers) {
    grpc::ClientContext context;
    AddToken(&context, client->token);
    v1::WatchJobRequest req;
    req.set_job_id(job_id);
    auto reader = client->stub->WatchJob(&context, req);
    v1::WatchJobResponse r;
    bool final = false;
    while (reader->Read(&r)) {
      final = IsFinal(r.job().state());
      on_update(r.job());
    }
    const grpc::Status st = reader->Finish();
    if (!several || final || failovers >= kMaxFailovers ||
        (st.error_code() != grpc::StatusCode::UNAVAILABLE &&
         st.error_code() != grpc::StatusCode::CANCELLED))
      return st;
    std::fprintf(stderr, "coordinator gone (%s); following job %s on the next one\n",
                 st.error_message().c_str(), job_id.c_str());
    Client next = Connect(c);
    if (!next.stub) return st;
    *client = std::move(next);
  }
}

void SetDeadline(grpc::ClientContext* c, const Client& client) {
  c->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(kRpcSeconds));
  AddToken(c, client.token);
}

int Fail(const grpc::Status& st) {
  std::fprintf(stderr, "error: %s: %s\n",
               absl::StatusCodeToString(absl::StatusCode(st.error_code())).c_str(),
               st.error_message().c_str());
  return 1;
}

int Fail(const absl::Status& st) {
  std::fprintf(stderr, "error: %s\n", st.ToString().c_str());
  return 1;
}

void PrintProgress(const v1::Job& job, bool tty) {
  // "\033[K" clears what a longer previous line left on the terminal.
  std::fprintf(stderr, "%s%s%s", tty ? "\r" : "", ProgressLine(job).c_str(), tty ? "\033[K" : "\n");
}

// Streams a file-like response (GetResult / ExportCache) into `path` via a temporary name, which
// is removed when anything fails; `check` (when given) judges the bytes before they are written.
template <typename Response, typename Call>
int StreamToFile(Call call, const std::string& path, const std::string& token,
                 const std::function<absl::Status(const std::string&)>& check = nullptr) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(600));
  AddToken(&context, token);
  std::string bytes;
  Response r;
  auto reader = call(&context);
  while (reader->Read(&r)) bytes += r.chunk();
  const grpc::Status st = reader->Finish();
  if (!st.ok()) return Fail(st);
  if (check) {
    if (absl::Status ok = check(bytes); !ok.ok()) return Fail(ok);
  }
  const std::string tmp = path + ".tmp." + std::to_string(getpid());
  // POSIX calls, so that the reason is the errno of the call that failed (an ofstream's is not
  // set reliably: a full disk read "Success").
  const auto failed = [&](const std::string& what, int err) {
    std::remove(tmp.c_str());
    return Fail(absl::InternalError(path + ": " + what + ": " + std::strerror(err)));
  };
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return failed("cannot create " + tmp, errno);
  for (size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      return failed("cannot write " + tmp, err);
    }
    done += size_t(n);
  }
  if (::close(fd) != 0) return failed("cannot write " + tmp, errno);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) return failed("cannot rename into place", errno);
  return 0;
}

}  // namespace

std::string DefaultCoordinator() {
  const char* env = std::getenv("IRFARM_COORDINATOR");
  return env && *env ? env : "127.0.0.1:50051";
}

int RunSubmit(const SubmitArgs& args) {
  Client client = Connect(args.coordinator);
  if (!client.stub) return Fail(client.status);
  auto& stub = client.stub;
  std::string snapshot;
  if (!args.cache_in.empty()) {
    std::ifstream in(args.cache_in, std::ios::binary);
    if (!in) return Fail(absl::NotFoundError(args.cache_in + ": cannot open"));
    std::ostringstream ss;
    ss << in.rdbuf();
    snapshot = ss.str();
    absl::StatusOr<Snapshot> parsed = ParseSnapshot(snapshot, args.cache_in);
    if (!parsed.ok()) return Fail(parsed.status());
  }
  std::vector<std::string> ids;
  for (const std::string& scene : args.scenes) {
    v1::SubmitJobRequest req;
    if (args.shared_path) {
      req.mutable_scene()->set_path(scene);
    } else {
      absl::StatusOr<v1::SceneBundle> bundle = MakeBundle(scene);
      if (!bundle.ok()) return Fail(bundle.status());
      *req.mutable_scene()->mutable_bundle() = std::move(*bundle);
    }
    v1::RenderSettings* s = req.mutable_settings();
    s->set_integrator(args.integrator);
    s->set_spp(args.spp);
    s->set_accuracy(args.accuracy);
    s->set_record_rays(args.record_rays);
    s->set_tile_size(args.tile_size);
    s->set_share_records(!args.no_share);
    s->set_seed(args.seed);
    s->set_no_overture(args.no_overture);
    s->set_no_caustics(args.no_caustics);
    s->set_no_firefly_filter(args.no_firefly_filter);
    s->set_denoise(args.denoise);
    s->set_target_error(args.target_error);
    s->set_tile_time_limit(args.tile_time_limit);
    for (const std::string& d : args.defines) {
      const size_t eq = d.find('=');
      if (eq == std::string::npos || eq == 0) {
        std::fprintf(stderr, "error: -D expects name=value, got '%s'\n", d.c_str());
        return 2;
      }
      (*s->mutable_defines())[d.substr(0, eq)] = d.substr(eq + 1);
    }
    req.set_priority(args.priority);
    req.set_name(scene);
    req.set_cache_snapshot(snapshot);
    grpc::ClientContext context;
    SetDeadline(&context, client);
    v1::SubmitJobResponse resp;
    const grpc::Status st = stub->SubmitJob(&context, req, &resp);
    if (!st.ok()) return Fail(st);
    std::printf("%s\n", resp.job().id().c_str());
    std::fflush(stdout);
    ids.push_back(resp.job().id());
  }
  if (!args.wait) return 0;
  const bool tty = !args.quiet && isatty(STDERR_FILENO);
  for (size_t i = 0; i < ids.size(); ++i) {
    v1::Job last;
    const grpc::Status st = FollowJob(args.coordinator, &client, ids[i], [&](const v1::Job& job) {
      last = job;
      if (!args.quiet && (tty || IsFinal(last.state()))) PrintProgress(last, tty);
    });
    if (tty) std::fprintf(stderr, "\n");
    if (!st.ok()) return Fail(st);
    if (last.state() != v1::JOB_STATE_SUCCEEDED) {
      std::fprintf(stderr, "error: job %s %s: %s\n", ids[i].c_str(),
                   StateName(last.state()).c_str(), last.error().c_str());
      return 1;
    }
    if (!args.output.empty()) {
      std::string out = args.output;
      if (ids.size() > 1) out = NumberedPath(out, i);
      const int code = RunFetch(args.coordinator, ids[i], out);
      if (code != 0) return code;
    }
  }
  return 0;
}

int RunStatus(const ServiceConnection& coordinator, const std::string& job_id, bool json,
              bool workers) {
  Client client = Connect(coordinator);
  if (!client.stub) return Fail(client.status);
  auto& stub = client.stub;
  std::vector<v1::Job> jobs;
  grpc::ClientContext context;
  SetDeadline(&context, client);
  if (workers) {
    v1::GetClusterResponse resp;
    const grpc::Status st = stub->GetCluster(&context, v1::GetClusterRequest(), &resp);
    if (!st.ok()) return Fail(st);
    if (json) {
      std::string text;
      google::protobuf::util::JsonPrintOptions o;
      o.always_print_primitive_fields = true;
      (void)google::protobuf::util::MessageToJsonString(resp, &text, o);
      std::printf("%s\n", text.c_str());
      return 0;
    }
    for (const v1::WorkerInfo& w : resp.workers()) {
      const std::string left =
          w.quarantined() ? " (" + std::to_string(int(w.quarantine_seconds_left())) + " s left)"
                          : "";
      std::printf("worker %-4u %-24s %-9s %-14s failures %u  violations %u  heard %.1f s ago%s\n",
                  w.id(), w.name().c_str(), w.has_lease() ? "leased" : "idle",
                  w.quarantined() ? "QUARANTINED"
                  : w.silent()    ? "SILENT"
                                  : "ok",
                  w.consecutive_failures(), w.violations(), w.seconds_since_heard(), left.c_str());
    }
    std::printf("auth failures %llu, invalid worker messages %llu, workers disconnected %llu\n",
                static_cast<unsigned long long>(resp.auth_failures()),
                static_cast<unsigned long long>(resp.worker_violations()),
                static_cast<unsigned long long>(resp.workers_disconnected()));
    return 0;
  }
  if (job_id.empty()) {
    v1::ListJobsResponse resp;
    const grpc::Status st = stub->ListJobs(&context, v1::ListJobsRequest(), &resp);
    if (!st.ok()) return Fail(st);
    jobs.assign(resp.jobs().begin(), resp.jobs().end());
  } else {
    v1::GetJobRequest req;
    req.set_job_id(job_id);
    v1::GetJobResponse resp;
    const grpc::Status st = stub->GetJob(&context, req, &resp);
    if (!st.ok()) return Fail(st);
    jobs.push_back(resp.job());
  }
  for (const v1::Job& job : jobs) {
    if (json) {
      std::string text;
      google::protobuf::util::JsonPrintOptions o;
      o.always_print_primitive_fields = true;
      (void)google::protobuf::util::MessageToJsonString(job, &text, o);
      std::printf("%s\n", text.c_str());
      continue;
    }
    std::printf("%s  prio %d  %s%s%s\n", ProgressLine(job).c_str(), job.priority(),
                job.name().c_str(), job.error().empty() ? "" : "  error: ", job.error().c_str());
  }
  return 0;
}

int RunCancel(const ServiceConnection& coordinator, const std::string& job_id) {
  Client client = Connect(coordinator);
  if (!client.stub) return Fail(client.status);
  auto& stub = client.stub;
  grpc::ClientContext context;
  SetDeadline(&context, client);
  v1::CancelJobRequest req;
  req.set_job_id(job_id);
  v1::CancelJobResponse resp;
  const grpc::Status st = stub->CancelJob(&context, req, &resp);
  if (!st.ok()) return Fail(st);
  std::printf("%s %s\n", job_id.c_str(), StateName(resp.job().state()).c_str());
  return 0;
}

int RunDelete(const ServiceConnection& coordinator, const std::string& job_id) {
  Client client = Connect(coordinator);
  if (!client.stub) return Fail(client.status);
  grpc::ClientContext context;
  SetDeadline(&context, client);
  v1::DeleteJobRequest req;
  req.set_job_id(job_id);
  v1::DeleteJobResponse resp;
  const grpc::Status st = client.stub->DeleteJob(&context, req, &resp);
  if (!st.ok()) return Fail(st);
  std::printf("%s deleted\n", job_id.c_str());
  return 0;
}

int RunWatch(const ServiceConnection& coordinator, const std::string& job_id) {
  Client client = Connect(coordinator);
  if (!client.stub) return Fail(client.status);
  const bool tty = isatty(STDOUT_FILENO);
  v1::Job last;
  bool printed_last = true;
  auto next_print = std::chrono::steady_clock::now();
  const grpc::Status st = FollowJob(coordinator, &client, job_id, [&](const v1::Job& job) {
    last = job;
    const auto now = std::chrono::steady_clock::now();
    // Updates come with every tile and record batch: a terminal is redrawn at most 10 times a
    // second, a log gets at most a line a second (and always the last state).
    if (now < next_print && !IsFinal(last.state())) {
      printed_last = false;
      return;
    }
    std::printf("%s%s%s", tty ? "\r" : "", ProgressLine(last).c_str(), tty ? "\033[K" : "\n");
    std::fflush(stdout);
    printed_last = true;
    next_print = now + std::chrono::milliseconds(tty ? 100 : 1000);
  });
  if (!printed_last) std::printf("%s%s", tty ? "\r" : "", ProgressLine(last).c_str());
  if (tty || !printed_last) std::printf("\n");
  if (!st.ok()) return Fail(st);
  if (last.state() != v1::JOB_STATE_SUCCEEDED) {
    std::fprintf(stderr, "error: job %s %s%s%s\n", job_id.c_str(), StateName(last.state()).c_str(),
                 last.error().empty() ? "" : ": ", last.error().c_str());
    return 1;
  }
  return 0;
}

int RunFetch(const ServiceConnection& coordinator, const std::string& job_id,
             const std::string& output) {
  Client client = Connect(coordinator);
  if (!client.stub) return Fail(client.status);
  v1::GetResultRequest req;
  req.set_job_id(job_id);
  return StreamToFile<v1::GetResultResponse>(
      [&](grpc::ClientContext* c) { return client.stub->GetResult(c, req); }, output, client.token);
}

int RunSnapshot(const ServiceConnection& coordinator, const std::string& job_id,
                const std::string& output) {
  Client client = Connect(coordinator);
  if (!client.stub) return Fail(client.status);
  v1::ExportCacheRequest req;
  req.set_job_id(job_id);
  return StreamToFile<v1::ExportCacheResponse>(
      [&](grpc::ClientContext* c) { return client.stub->ExportCache(c, req); }, output,
      client.token,
      [&](const std::string& bytes) {
        // What `render --cache-in` and a job's snapshot upload will read: checked now, so a
        // snapshot that cannot be read back is not written.
        return ParseSnapshot(bytes, "snapshot of " + job_id).status();
      });
}

}  // namespace irfarm

// Authenticator: who may call the coordinator. Clients and workers present a bearer token in
// the gRPC metadata `authorization: Bearer <token>`; the coordinator knows separate client,
// worker and (optional) admin tokens, each read from a file with one token per line, either
// "TOKEN" or "NAME TOKEN" (blank lines and lines starting with '#' are skipped). A client's name
// owns the jobs it submits (JobManager's Caller); an admin token sees every job. Tokens are
// compared in constant time (all of them, every time), so timing does not reveal a prefix.
// A role with no tokens configured is open (loopback development); coordinator/main.cc refuses
// to listen on a non-loopback address that way unless told --insecure. Every refusal is logged
// with the peer and counted. Thread-safe.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "coordinator/job_manager.h"

namespace irfarm {

struct NamedToken {
  std::string name, token;
};

// Reads a token file (format above). INVALID_ARGUMENT for a token shorter than 16 bytes or a
// file without tokens; NOT_FOUND when it cannot be read. Unnamed tokens are called
// `default_prefix` + line number.
absl::StatusOr<std::vector<NamedToken>> ReadTokenFile(const std::string& path,
                                                      const std::string& default_prefix);

// True when a and b are equal, in time that depends only on their lengths.
bool ConstantTimeEqual(const std::string& a, const std::string& b);

class Authenticator {
 public:
  Authenticator() = default;  // no tokens: everything open
  Authenticator(std::vector<NamedToken> clients, std::vector<NamedToken> workers,
                std::vector<NamedToken> admins)
      : clients_(std::move(clients)), workers_(std::move(workers)), admins_(std::move(admins)) {}

  bool clients_open() const { return clients_.empty() && admins_.empty(); }
  bool workers_open() const { return workers_.empty(); }

  // The job API caller, or UNAUTHENTICATED (logged and counted) without a client or admin token.
  absl::StatusOr<Caller> Client(const grpc::ServerContext& context);
  // The same for an HTTP request (the dashboard): `authorization` is its Authorization header
  // ("Bearer <token>"), `peer` its remote address for the log.
  absl::StatusOr<Caller> HttpClient(const std::string& authorization, const std::string& peer);
  // The name of the worker token the caller presented ("" when workers need none), else
  // UNAUTHENTICATED (logged and counted). A worker's own name is whatever it registers with; the
  // token's is what the coordinator knows it by (failure history, quarantine).
  absl::StatusOr<std::string> Worker(const grpc::ServerContext& context);

  uint64_t failures() const { return failures_.load(); }

 private:
  absl::Status Refuse(const grpc::ServerContext& context, const std::string& why);
  absl::Status Refuse(const std::string& peer, const std::string& why);
  absl::StatusOr<Caller> ClientByToken(const std::string& token, const std::string& peer);

  const std::vector<NamedToken> clients_{}, workers_{}, admins_{};
  std::atomic<uint64_t> failures_{0};
};

}  // namespace irfarm

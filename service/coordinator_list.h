// CoordinatorList: the coordinators a client or worker may talk to, from
// `--coordinator host1:port,host2:port` (one address works as before). With `irfarm-coordinator
// --ha` only the active coordinator listens, so "the one that accepts a connection" is the one
// to use: FindConnected asks every channel to connect and returns the first that is READY (the
// TLS handshake included), in list order when several are. A Kubernetes Service in front of the
// coordinators is one address and needs no list (its readiness probe keeps standbys out).
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace irfarm {

class CoordinatorList {
 public:
  // Splits a comma-separated list (spaces around addresses ignored). INVALID_ARGUMENT for an
  // empty list or an empty entry.
  static absl::StatusOr<std::vector<std::string>> Parse(const std::string& list);

  // One channel per address, made now (they connect lazily).
  CoordinatorList(std::vector<std::string> addresses,
                  const std::shared_ptr<grpc::ChannelCredentials>& credentials,
                  const grpc::ChannelArguments& args);

  // The index of a coordinator whose channel is connected, waiting until one is or `deadline`
  // (nullopt then). A channel whose last attempt failed retries after gRPC's reconnect backoff
  // (GRPC_ARG_MAX_RECONNECT_BACKOFF_MS bounds how late a coordinator that starts listening is
  // seen).
  std::optional<size_t> FindConnected(std::chrono::system_clock::time_point deadline);

  size_t size() const { return channels_.size(); }
  const std::string& address(size_t i) const { return addresses_[i]; }
  const std::shared_ptr<grpc::Channel>& channel(size_t i) const { return channels_[i]; }
  // "host1:port,host2:port", for messages.
  std::string ToString() const;

 private:
  std::vector<std::string> addresses_;
  std::vector<std::shared_ptr<grpc::Channel>> channels_;
};

}  // namespace irfarm

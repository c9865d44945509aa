// Client-side credentials for talking to a coordinator, shared by the `irfarm` service commands
// and irfarm-worker: the bearer token (from --token-file, else the IRFARM_TOKEN environment
// variable), sent as `authorization: Bearer <token>` metadata on every call, and the channel's
// transport: plaintext, or TLS trusting --tls-ca, with a client certificate (--tls-cert,
// --tls-key) for a coordinator that requires one (mutual TLS).
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

#include "absl/status/statusor.h"

namespace irfarm {

struct ClientAuthOptions {
  std::string token_file;         // first "TOKEN" or "NAME TOKEN" line; empty: $IRFARM_TOKEN
  std::string tls_ca;             // PEM roots to verify the coordinator with; empty: no TLS
  std::string tls_cert, tls_key;  // PEM client certificate and key (mutual TLS)
};

// The token to send ("" for none). NOT_FOUND / INVALID_ARGUMENT for an unreadable or empty file.
absl::StatusOr<std::string> LoadClientToken(const ClientAuthOptions& options);

// Channel credentials for `options` (insecure without tls_ca).
absl::StatusOr<std::shared_ptr<grpc::ChannelCredentials>> MakeChannelCredentials(
    const ClientAuthOptions& options);

// Adds the bearer token (if any) to a call.
void AddToken(grpc::ClientContext* context, const std::string& token);

}  // namespace irfarm

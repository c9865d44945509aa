// Authenticator: bearer tokens from gRPC metadata, constant-time checks (see auth.h).
#include "coordinator/auth.h"

#include <spdlog/spdlog.h>

#include <fstream>
#include <sstream>

namespace irfarm {
namespace {

constexpr size_t kMinTokenBytes = 16;

// The bearer token of the call, or "" when there is none.
std::string BearerToken(const grpc::ServerContext& context) {
  const auto& md = context.client_metadata();
  auto it = md.find("authorization");
  if (it == md.end()) return "";
  const std::string value(it->second.data(), it->second.size());
  const std::string prefix = "Bearer ";
  if (value.compare(0, prefix.size(), prefix) != 0) return "";
  return value.substr(prefix.size());
}

// The entry whose token equals `token`, checking every entry (no early exit).
const NamedToken* Match(const std::vector<NamedToken>& tokens, const std::string& token) {
  const NamedToken* found = nullptr;
  for (const NamedToken& t : tokens)
    if (ConstantTimeEqual(t.token, token) && found == nullptr) found = &t;
  return found;
}

}  // namespace

bool ConstantTimeEqual(const std::string& a, const std::string& b) {
  const size_t n = std::max(a.size(), b.size());
  unsigned diff = a.size() == b.size() ? 0u : 1u;
  for (size_t i = 0; i < n; ++i) {
    const unsigned char x = i < a.size() ? static_cast<unsigned char>(a[i]) : 0;
    const unsigned char y = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    diff |= unsigned(x ^ y);
  }
  return diff == 0;
}

absl::StatusOr<std::vector<NamedToken>> ReadTokenFile(const std::string& path,
                                                      const std::string& default_prefix) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(path + ": cannot read the token file");
  std::vector<NamedToken> out;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    std::istringstream ss(line);
    std::vector<std::string> words;
    for (std::string w; ss >> w;) words.push_back(w);
    if (words.empty() || words[0][0] == '#') continue;
    if (words.size() > 2)
      return absl::InvalidArgumentError(path + ":" + std::to_string(number) +
                                        ": expected 'TOKEN' or 'NAME TOKEN'");
    NamedToken t;
    t.name = words.size() == 2 ? words[0] : default_prefix + std::to_string(number);
    t.token = words.back();
    if (t.token.size() < kMinTokenBytes)
      return absl::InvalidArgumentError(path + ":" + std::to_string(number) +
                                        ": token shorter than " + std::to_string(kMinTokenBytes) +
                                        " bytes");
    out.push_back(std::move(t));
  }
  if (out.empty()) return absl::InvalidArgumentError(path + ": no tokens");
  return out;
}

absl::Status Authenticator::Refuse(const grpc::ServerContext& context, const std::string& why) {
  return Refuse(context.peer(), why);
}

absl::Status Authenticator::Refuse(const std::string& peer, const std::string& why) {
  ++failures_;
  spdlog::warn("refused {}: {}", peer, why);
  return absl::UnauthenticatedError(why);
}

absl::StatusOr<Caller> Authenticator::ClientByToken(const std::string& token,
                                                    const std::string& peer) {
  if (clients_open()) return Caller();
  if (token.empty()) return Refuse(peer, "no bearer token (authorization: Bearer <token>)");
  const NamedToken* admin = Match(admins_, token);
  const NamedToken* client = Match(clients_, token);
  if (admin != nullptr) return Caller{admin->name, true};
  if (client != nullptr) return Caller{client->name, false};
  return Refuse(peer, "not a valid client token");
}

absl::StatusOr<Caller> Authenticator::Client(const grpc::ServerContext& context) {
  return ClientByToken(BearerToken(context), context.peer());
}

absl::StatusOr<Caller> Authenticator::HttpClient(const std::string& authorization,
                                                 const std::string& peer) {
  const std::string prefix = "Bearer ";
  return ClientByToken(authorization.compare(0, prefix.size(), prefix) == 0
                           ? authorization.substr(prefix.size())
                           : "",
                       peer);
}

absl::StatusOr<std::string> Authenticator::Worker(const grpc::ServerContext& context) {
  if (workers_open()) return std::string();
  const std::string token = BearerToken(context);
  if (token.empty()) return Refuse(context, "no bearer token (authorization: Bearer <token>)");
  const NamedToken* match = Match(workers_, token);
  if (match == nullptr) return Refuse(context, "not a valid worker token");
  return match->name;
}

}  // namespace irfarm

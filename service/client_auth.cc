// Client credentials: token file / IRFARM_TOKEN, TLS channel credentials (see client_auth.h).
#include "service/client_auth.h"

#include <cstdlib>
#include <fstream>
#include <sstream>

namespace irfarm {
namespace {

absl::StatusOr<std::string> ReadAll(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(path + ": cannot read the " + what);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

absl::StatusOr<std::string> LoadClientToken(const ClientAuthOptions& options) {
  if (options.token_file.empty()) {
    const char* env = std::getenv("IRFARM_TOKEN");
    return std::string(env != nullptr ? env : "");
  }
  absl::StatusOr<std::string> text = ReadAll(options.token_file, "token file");
  if (!text.ok()) return text.status();
  std::istringstream lines(*text);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream ss(line);
    std::string word, last;
    while (ss >> word) {
      if (last.empty() && word[0] == '#') break;
      last = word;
    }
    if (!last.empty()) return last;
  }
  return absl::InvalidArgumentError(options.token_file + ": no token");
}

absl::StatusOr<std::shared_ptr<grpc::ChannelCredentials>> MakeChannelCredentials(
    const ClientAuthOptions& options) {
  if (options.tls_ca.empty()) {
    if (!options.tls_cert.empty() || !options.tls_key.empty())
      return absl::InvalidArgumentError("--tls-cert/--tls-key need --tls-ca");
    return grpc::InsecureChannelCredentials();
  }
  grpc::SslCredentialsOptions ssl;
  absl::StatusOr<std::string> ca = ReadAll(options.tls_ca, "CA certificate");
  if (!ca.ok()) return ca.status();
  ssl.pem_root_certs = *ca;
  if (!options.tls_cert.empty() || !options.tls_key.empty()) {
    absl::StatusOr<std::string> cert = ReadAll(options.tls_cert, "client certificate");
    if (!cert.ok()) return cert.status();
    absl::StatusOr<std::string> key = ReadAll(options.tls_key, "client key");
    if (!key.ok()) return key.status();
    ssl.pem_cert_chain = *cert;
    ssl.pem_private_key = *key;
  }
  return grpc::SslCredentials(ssl);
}

void AddToken(grpc::ClientContext* context, const std::string& token) {
  if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
}

}  // namespace irfarm

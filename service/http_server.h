// HttpServer: a small HTTP/1.1 server on its own threads, for what the coordinator and the worker
// serve besides gRPC: Prometheus metrics (`--metrics ADDR`, GET /metrics) and the coordinator's
// dashboard. Built on cpp-httplib (Debian's libcpp-httplib-dev), kept out of this header so that
// only http_server.cc compiles it. Routes match the path exactly (no patterns); parameters come
// from the query string (or a form body). Requests are handled by a pool of 2 threads, one request
// per connection: these are scrapes and a dashboard's polls, not a data path.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace irfarm {

struct HttpRequest {
  std::string method, path;
  std::map<std::string, std::string> params;   // query string and form fields
  std::map<std::string, std::string> headers;  // names lower-case
  std::string peer;                            // remote address, for logs
};

struct HttpResponse {
  int status = 200;
  std::string content_type = "text/plain; charset=utf-8";
  std::string body;
};

struct HttpRoute {
  std::string method;  // "GET" or "POST"
  std::string path;    // exact, e.g. "/metrics"
  std::function<HttpResponse(const HttpRequest&)> handler;
};

class HttpServer {
 public:
  // Listens on HOST:PORT (PORT 0: any free port, see port()) and serves `routes`; others get 404.
  // INVALID_ARGUMENT for a malformed address, UNAVAILABLE when the port cannot be bound.
  static absl::StatusOr<std::unique_ptr<HttpServer>> Start(const std::string& address,
                                                           std::vector<HttpRoute> routes);
  ~HttpServer();  // stops listening and joins its threads
  int port() const { return port_; }

 private:
  struct Impl;
  HttpServer() = default;
  std::unique_ptr<Impl> impl_;
  int port_ = 0;
};

}  // namespace irfarm

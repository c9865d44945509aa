// The dashboard's routes (coordinator/dashboard.h) called directly: an open dashboard (no client
// tokens) answers only requests whose Host is this machine's loopback. A web page whose name an
// attacker rebinds to 127.0.0.1 is same-origin with the dashboard (it can send X-Irfarm-Request),
// but its requests carry its own name as Host: they get 421, for the page and for every API
// route, GET and POST. With client tokens the token decides, whatever the Host.
#include <gtest/gtest.h>

#include "coordinator/auth.h"
#include "coordinator/dashboard.h"
#include "coordinator/in_memory_job_store.h"
#include "coordinator/job_manager.h"

namespace irfarm {
namespace {

HttpResponse Call(const std::vector<HttpRoute>& routes, const std::string& method,
                  const std::string& path, const std::string& host, const std::string& token = "") {
  HttpRequest r;
  r.method = method;
  r.path = path;
  r.peer = "127.0.0.1:40000";
  r.headers["host"] = host;
  if (method == "POST") r.headers["x-irfarm-request"] = "1";
  if (!token.empty()) r.headers["authorization"] = "Bearer " + token;
  r.params["job"] = "job-1";
  r.params["priority"] = "5";
  for (const HttpRoute& route : routes)
    if (route.method == method && route.path == path) return route.handler(r);
  ADD_FAILURE() << "no route " << method << " " << path;
  return HttpResponse{};
}

TEST(DashboardHostTest, AnOpenDashboardAnswersOnlyItsLoopbackNames) {
  InMemoryJobStore store;
  std::unique_ptr<JobManager> manager = std::move(*JobManager::Create(JobManagerOptions(), &store));
  const std::vector<HttpRoute> routes = DashboardRoutes(manager.get(), nullptr);
  const std::pair<const char*, const char*> all[] = {{"GET", "/"},
                                                     {"GET", "/api/jobs"},
                                                     {"GET", "/api/workers"},
                                                     {"GET", "/api/image.png"},
                                                     {"GET", "/api/record_map.png"},
                                                     {"POST", "/api/cancel"},
                                                     {"POST", "/api/priority"}};
  for (const auto& [method, path] : all) {
    // Names that start like a loopback address are names (they passed a prefix match before).
    for (const char* host :
         {"evil.example", "evil.example:8080", "10.0.0.5:8080", "", "127.0.0.1.nip.io:8080",
          "127.evil.example", "localhost.evil.example", "[::1.evil]:8080", "128.0.0.1:8080"})
      EXPECT_EQ(Call(routes, method, path, host).status, 421)
          << method << " " << path << " " << host;
    for (const char* host : {"127.0.0.1:8080", "127.3.2.1", "localhost:8080", "LOCALHOST",
                             "[::1]:8080", "[0:0:0:0:0:0:0:1]:8080", "[::ffff:127.0.0.1]:80"}) {
      const int status = Call(routes, method, path, host).status;
      EXPECT_NE(status, 421) << method << " " << path << " " << host;
    }
  }
  EXPECT_EQ(Call(routes, "GET", "/api/jobs", "127.0.0.1:8080").status, 200);
}

TEST(DashboardHostTest, WithClientTokensTheTokenDecides) {
  InMemoryJobStore store;
  std::unique_ptr<JobManager> manager = std::move(*JobManager::Create(JobManagerOptions(), &store));
  Authenticator auth({{"alice", "alice-token-0123456789"}}, {}, {});
  const std::vector<HttpRoute> routes = DashboardRoutes(manager.get(), &auth);
  EXPECT_EQ(Call(routes, "GET", "/api/jobs", "farm.example.com", "alice-token-0123456789").status,
            200);
  EXPECT_EQ(Call(routes, "GET", "/api/jobs", "farm.example.com").status, 401);
}

}  // namespace
}  // namespace irfarm

// Dashboard endpoints: JSON and PNG views of the JobManager (see dashboard.h).
#include "coordinator/dashboard.h"

#include <google/protobuf/util/json_util.h>

#include "service/loopback.h"

namespace irfarm {
namespace {

HttpResponse Error(const absl::Status& st) {
  int code = 500;
  switch (st.code()) {
    case absl::StatusCode::kNotFound:
      code = 404;
      break;
    case absl::StatusCode::kInvalidArgument:
      code = 400;
      break;
    case absl::StatusCode::kFailedPrecondition:
      code = 409;
      break;
    case absl::StatusCode::kUnauthenticated:
      code = 401;
      break;
    case absl::StatusCode::kPermissionDenied:
      code = 403;
      break;
    case absl::StatusCode::kUnavailable:
      code = 503;
      break;
    default:
      break;
  }
  return HttpResponse{code, "text/plain; charset=utf-8", std::string(st.message()) + "\n"};
}

HttpResponse Json(const google::protobuf::Message& m) {
  std::string text;
  google::protobuf::util::JsonPrintOptions o;
  o.always_print_primitive_fields = true;
  (void)google::protobuf::util::MessageToJsonString(m, &text, o);
  return HttpResponse{200, "application/json", text};
}

std::string Param(const HttpRequest& r, const std::string& name) {
  auto it = r.params.find(name);
  return it == r.params.end() ? "" : it->second;
}

std::string Header(const HttpRequest& r, const std::string& name) {
  auto it = r.headers.find(name);
  return it == r.headers.end() ? "" : it->second;
}

// Whether the request's Host names this machine's loopback. An open dashboard (no client tokens)
// answers only those: a web page whose name an attacker rebinds to 127.0.0.1 (DNS rebinding) is
// same-origin with the dashboard and could send X-Irfarm-Request, but its requests carry its own
// name as Host.
bool LoopbackHost(const HttpRequest& r) {
  const std::string host = Header(r, "host");
  return !host.empty() && host.rfind("unix:", 0) != 0 && IsLoopbackAddress(host);
}

HttpResponse ForeignHost() {
  return HttpResponse{421, "text/plain; charset=utf-8",
                      "an open dashboard (no client tokens) answers only requests for "
                      "127.0.0.1, localhost or [::1]\n"};
}

}  // namespace

std::vector<HttpRoute> DashboardRoutes(JobManager* manager, Authenticator* auth) {
  const bool open = auth == nullptr || auth->clients_open();
  // Wraps an API handler: authenticates the caller, and for POSTs checks the anti-forgery header.
  const auto api = [auth, open](bool post, auto handler) {
    return [auth, open, post, handler](const HttpRequest& r) -> HttpResponse {
      if (open && !LoopbackHost(r)) return ForeignHost();
      if (post && Header(r, "x-irfarm-request") != "1")
        return HttpResponse{403, "text/plain; charset=utf-8",
                            "POST needs the header X-Irfarm-Request: 1\n"};
      absl::StatusOr<Caller> caller = Caller();
      if (auth != nullptr) caller = auth->HttpClient(Header(r, "authorization"), "http " + r.peer);
      if (!caller.ok()) return Error(caller.status());
      return handler(r, *caller);
    };
  };
  std::vector<HttpRoute> routes;
  routes.push_back({"GET", "/", [open](const HttpRequest& r) {
                      if (open && !LoopbackHost(r)) return ForeignHost();
                      return HttpResponse{200, "text/html; charset=utf-8", kDashboardHtml};
                    }});
  routes.push_back({"GET", "/api/jobs", api(false, [manager](const HttpRequest&, const Caller& c) {
                      v1::ListJobsResponse resp;
                      for (v1::Job& j : manager->ListJobs(c)) {
                        j.clear_settings();  // not shown; keeps defines out of the page
                        *resp.add_jobs() = std::move(j);
                      }
                      return Json(resp);
                    })});
  routes.push_back(
      {"GET", "/api/workers", api(false, [manager](const HttpRequest&, const Caller& c) {
         return Json(manager->Cluster(c));
       })});
  routes.push_back(
      {"GET", "/api/image.png", api(false, [manager](const HttpRequest& r, const Caller& c) {
         absl::StatusOr<Image> image = manager->Preview(Param(r, "job"), c);
         if (!image.ok()) return Error(image.status());
         absl::StatusOr<std::string> png = EncodePng(*image);
         if (!png.ok()) return Error(png.status());
         return HttpResponse{200, "image/png", std::move(*png)};
       })});
  routes.push_back(
      {"GET", "/api/record_map.png", api(false, [manager](const HttpRequest& r, const Caller& c) {
         absl::StatusOr<Image> map = manager->RecordMap(Param(r, "job"), c);
         if (!map.ok()) return Error(map.status());
         // Exposure 1: the palette's bytes come out exactly (record_map.h).
         absl::StatusOr<std::string> png = EncodePng(*map, 1.0f);
         if (!png.ok()) return Error(png.status());
         return HttpResponse{200, "image/png", std::move(*png)};
       })});
  routes.push_back(
      {"POST", "/api/cancel", api(true, [manager](const HttpRequest& r, const Caller& c) {
         absl::StatusOr<v1::Job> job = manager->Cancel(Param(r, "job"), c);
         return job.ok() ? Json(*job) : Error(job.status());
       })});
  routes.push_back(
      {"POST", "/api/priority", api(true, [manager](const HttpRequest& r, const Caller& c) {
         int priority = 0;
         try {
           size_t used = 0;
           const std::string p = Param(r, "priority");
           priority = std::stoi(p, &used);
           if (used != p.size()) throw 0;
         } catch (...) {
           return Error(absl::InvalidArgumentError("priority must be an integer"));
         }
         absl::StatusOr<v1::Job> job = manager->SetPriority(Param(r, "job"), priority, c);
         return job.ok() ? Json(*job) : Error(job.status());
       })});
  return routes;
}

}  // namespace irfarm

// HttpServer on cpp-httplib (see http_server.h).
#include "service/http_server.h"

#include <httplib.h>

#include <cctype>
#include <thread>

namespace irfarm {

struct HttpServer::Impl {
  httplib::Server server;
  std::thread thread;
};

absl::StatusOr<std::unique_ptr<HttpServer>> HttpServer::Start(const std::string& address,
                                                              std::vector<HttpRoute> routes) {
  const size_t colon = address.rfind(':');
  if (colon == std::string::npos || colon == 0)
    return absl::InvalidArgumentError("HTTP address must be HOST:PORT, got '" + address + "'");
  std::string host = address.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[') host = host.substr(1, host.size() - 2);
  int port = 0;
  try {
    size_t used = 0;
    port = std::stoi(address.substr(colon + 1), &used);
    if (used != address.size() - colon - 1 || port < 0 || port > 65535) throw 0;
  } catch (...) {
    return absl::InvalidArgumentError("bad port in HTTP address '" + address + "'");
  }
  std::unique_ptr<HttpServer> s(new HttpServer());
  s->impl_ = std::make_unique<Impl>();
  httplib::Server& server = s->impl_->server;
  server.new_task_queue = [] { return new httplib::ThreadPool(2); };
  // One request per connection: an idle keep-alive connection (a browser keeps several) would
  // hold one of the 2 threads for the keep-alive timeout and stall everyone else.
  server.set_keep_alive_max_count(1);
  server.set_read_timeout(5, 0);
  server.set_write_timeout(5, 0);
  // Request bodies are read before the route or the token is looked at: without a bound (httplib's
  // default is none) one POST of /dev/zero filled the process's memory. No route takes more than
  // a few bytes of body; past 64 KiB the answer is 413.
  server.set_payload_max_length(size_t(64) << 10);
  for (HttpRoute& route : routes) {
    auto handle = [handler = std::move(route.handler)](const httplib::Request& req,
                                                       httplib::Response& res) {
      HttpRequest r;
      r.method = req.method;
      r.path = req.path;
      r.peer = req.remote_addr + ":" + std::to_string(req.remote_port);
      for (const auto& [k, v] : req.params) r.params[k] = v;
      for (const auto& [k, v] : req.headers) {
        std::string name = k;
        for (char& c : name) c = char(std::tolower(static_cast<unsigned char>(c)));
        r.headers[name] = v;
      }
      HttpResponse out = handler(r);
      res.status = out.status;
      res.set_content(out.body, out.content_type.c_str());
      res.set_header("Cache-Control", "no-store");
    };
    // httplib takes a regex; the path is matched literally.
    std::string pattern;
    for (char c : route.path) {
      if (std::isalnum(static_cast<unsigned char>(c)) || c == '/' || c == '_' || c == '-') {
        pattern += c;
      } else {
        pattern += std::string("\\") + c;
      }
    }
    if (route.method == "POST") {
      server.Post(pattern, handle);
    } else {
      server.Get(pattern, handle);
    }
  }
  if (port == 0) {
    port = server.bind_to_any_port(host);
    if (port <= 0) return absl::UnavailableError("cannot listen on " + address);
  } else if (!server.bind_to_port(host, port)) {
    return absl::UnavailableError("cannot listen on " + address);
  }
  s->port_ = port;
  s->impl_->thread = std::thread([impl = s->impl_.get()] { impl->server.listen_after_bind(); });
  return s;
}

HttpServer::~HttpServer() {
  if (!impl_) return;
  // stop() only acts on a running server: wait (bounded) for the thread to have started it.
  for (int i = 0; i < 400 && !impl_->server.is_running(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  impl_->server.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

}  // namespace irfarm

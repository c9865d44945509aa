// Test helpers for the tests that need a real Redis: a free loopback port, and a redis-server
// child process on it with a temp dir and no persistence, killed (SIGKILL) when destroyed. The
// pid is exposed so that a test can SIGSTOP / SIGCONT it (a hung Redis).
#pragma once

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include "coordinator/redis_job_store.h"
#include "service/free_port.h"
#include "service/scene_bundle.h"

namespace irfarm {

class RedisServer {
 public:
  RedisServer() {
    dir_ = *MakeTempDir("irfarm-redis-test-");
    port_ = FreePort();
    pid_ = fork();
    if (pid_ == 0) {
      const std::string port = std::to_string(port_);
      execlp("redis-server", "redis-server", "--port", port.c_str(), "--bind", "127.0.0.1", "--dir",
             dir_.c_str(), "--save", "", "--appendonly", "no", "--logfile",
             (dir_ + "/redis.log").c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
  }
  ~RedisServer() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
    RemoveTree(dir_);
  }
  RedisServer(const RedisServer&) = delete;
  RedisServer& operator=(const RedisServer&) = delete;

  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  // Stops the server (SIGSTOP: a hung Redis) and waits until /proc shows it stopped ('T' in
  // /proc/PID/stat; kill() returns before the stop takes hold), at most `limit`.
  bool Hang(std::chrono::milliseconds limit = std::chrono::seconds(5)) const {
    if (kill(pid_, SIGSTOP) != 0) return false;
    const auto end = std::chrono::steady_clock::now() + limit;
    do {
      std::ifstream stat("/proc/" + std::to_string(pid_) + "/stat");
      std::string line;
      std::getline(stat, line);
      const size_t close = line.rfind(')');  // the command name may hold spaces
      if (close != std::string::npos && close + 2 < line.size() && line[close + 2] == 'T')
        return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    } while (std::chrono::steady_clock::now() < end);
    return false;
  }
  void Resume() const { kill(pid_, SIGCONT); }
  // A store connected to this server, retried for up to 5 s while it starts; null if it never
  // answered.
  std::unique_ptr<RedisJobStore> Connect(const RedisOptions& options = RedisOptions()) const {
    for (int i = 0; i < 100; ++i) {
      absl::StatusOr<std::unique_ptr<RedisJobStore>> s = RedisJobStore::Connect(address(), options);
      if (s.ok()) return std::move(*s);
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return nullptr;
  }

 private:
  std::string dir_;
  int port_ = 0;
  pid_t pid_ = -1;
};

}  // namespace irfarm

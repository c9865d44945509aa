// Helpers for the benches that start real service processes (service_scaling.cc, scale_sim.cc):
// a free loopback port, a child process with its output in a log file (SIGTERM, then SIGKILL, on
// Stop), a log-contains check, a wait for a TCP port to accept, a wait for a coordinator's job API
// to answer, and the CPU time and memory of a process read from /proc (Linux only).
#pragma once

#include <fcntl.h>
#include <grpcpp/grpcpp.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "irfarm/v1/jobs.grpc.pb.h"
#include "service/free_port.h"

namespace irfarm {

// A child process (argv[0] is looked up on PATH when it has no '/') with its stdout and stderr
// in `log`; stopped by Stop() or the destructor.
class ChildProcess {
 public:
  ChildProcess(const std::vector<std::string>& argv, const std::string& log) {
    pid_ = fork();
    if (pid_ == 0) {
      const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd >= 0) {
        dup2(fd, 1);
        dup2(fd, 2);
      }
      std::vector<char*> args;
      for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      execvp(args[0], args.data());
      _exit(127);
    }
  }
  ~ChildProcess() { Stop(); }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  // True while the process has not exited.
  bool Running() {
    if (pid_ <= 0) return false;
    if (waitpid(pid_, nullptr, WNOHANG) == pid_) {
      pid_ = 0;
      return false;
    }
    return true;
  }
  // SIGTERM, then SIGKILL after 5 s.
  void Stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    for (int i = 0; i < 100; ++i) {
      if (waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = 0;
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = 0;
  }

 private:
  pid_t pid_ = 0;
};

inline bool LogContains(const std::string& path, const std::string& text) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str().find(text) != std::string::npos;
}

// Waits until something accepts TCP connections on 127.0.0.1:port.
inline bool WaitForPort(int port, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(uint16_t(port));
    const bool up = connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    close(fd);
    if (up) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

// Waits up to `timeout` for the coordinator behind `stub` to answer ListJobs.
inline bool WaitForJobService(v1::JobService::Stub* stub, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    grpc::ClientContext c;
    c.set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(200));
    v1::ListJobsResponse r;
    if (stub->ListJobs(&c, v1::ListJobsRequest(), &r).ok()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

// CPU time (user + system, seconds) and memory of a process, from /proc/PID/stat and status.
struct ProcessUsage {
  bool ok = false;
  double cpu_seconds = 0;
  double rss_mib = 0;   // VmRSS
  double peak_mib = 0;  // VmHWM: the largest RSS so far
};

inline ProcessUsage ReadProcessUsage(pid_t pid) {
  ProcessUsage u;
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(stat, line)) return u;
  // Fields after the command name, which is in parentheses and may contain spaces: state is
  // field 3, utime field 14 and stime field 15 (clock ticks).
  const size_t close = line.rfind(')');
  if (close == std::string::npos) return u;
  std::istringstream rest(line.substr(close + 2));
  std::string field;
  unsigned long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && rest >> field; ++i) {
    if (i == 14) utime = std::stoull(field);
    if (i == 15) stime = std::stoull(field);
  }
  u.cpu_seconds = double(utime + stime) / double(sysconf(_SC_CLK_TCK));
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  while (std::getline(status, line)) {
    unsigned long kib = 0;
    if (std::sscanf(line.c_str(), "VmRSS: %lu kB", &kib) == 1) u.rss_mib = double(kib) / 1024;
    if (std::sscanf(line.c_str(), "VmHWM: %lu kB", &kib) == 1) u.peak_mib = double(kib) / 1024;
  }
  u.ok = true;
  return u;
}

}  // namespace irfarm

// UnixMs: the wall clock in milliseconds since the epoch, as the protocol's *_unix_ms fields
// carry it (lease deadlines, job finish times).
#pragma once

#include <chrono>
#include <cstdint>

namespace irfarm {

inline int64_t UnixMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace irfarm

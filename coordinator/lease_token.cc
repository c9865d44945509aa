// LeaseToken: 128-bit random lease tokens (see lease_token.h).
#include "coordinator/lease_token.h"

#include <sys/random.h>

#include <cstring>
#include <random>

namespace irfarm {

static_assert(sizeof(uint64_t[2]) == LeaseToken::kBytes, "two words make a token");

LeaseToken LeaseToken::Random() {
  LeaseToken t;
  while (t.empty()) {
    // 16 bytes never come back short from getrandom (requests up to 256 bytes are not split);
    // it fails only without the syscall (old kernels, some sandboxes).
    if (getrandom(t.words_, sizeof t.words_, 0) != ssize_t(sizeof t.words_)) {
      std::random_device rd;  // on Linux also the kernel's CSPRNG (/dev/urandom)
      for (uint64_t& w : t.words_) w = (uint64_t(rd()) << 32) ^ rd();
    }
  }
  return t;
}

std::optional<LeaseToken> LeaseToken::FromBytes(std::string_view bytes) {
  if (bytes.size() != kBytes) return std::nullopt;
  LeaseToken t;
  std::memcpy(t.words_, bytes.data(), kBytes);
  return t;
}

std::string LeaseToken::Bytes() const {
  return std::string(reinterpret_cast<const char*>(words_), kBytes);
}

}  // namespace irfarm

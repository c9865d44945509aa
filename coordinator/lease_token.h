// LeaseToken: the name and the proof of one tile lease. The coordinator draws 128 bits from the
// kernel's CSPRNG for every lease it gives; the worker sends the 16 bytes back (`lease_token`) in
// every message about that lease (tile result, tile failure, tile region), and the coordinator
// accepts such a message only from the worker the lease was given to and only when all 128 bits
// match. Why 128 and not 64: a foreign worker guessing at 1e6 messages per second for a year
// (2^45 guesses, reconnecting after each expulsion) finds one given live lease with probability
// 2^-19 against 64 bits, 2^-83 against 128. The all-zero token is never issued (it stands for
// "no lease").
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace irfarm {

class LeaseToken {
 public:
  static constexpr size_t kBytes = 16;

  LeaseToken() = default;  // the all-zero token: no lease
  // 16 bytes from getrandom (std::random_device if that fails), never all zero.
  static LeaseToken Random();
  // The token a worker sent (TileResult.lease_token, ...); nullopt unless exactly kBytes long.
  static std::optional<LeaseToken> FromBytes(std::string_view bytes);
  // The kBytes bytes sent in TileLease.lease_token (FromBytes(Bytes()) == *this).
  std::string Bytes() const;
  bool empty() const { return (words_[0] | words_[1]) == 0; }

  // All 128 bits, with no early exit (the time taken does not tell how much of a guess matched).
  friend bool operator==(const LeaseToken& a, const LeaseToken& b) {
    return ((a.words_[0] ^ b.words_[0]) | (a.words_[1] ^ b.words_[1])) == 0;
  }
  friend bool operator!=(const LeaseToken& a, const LeaseToken& b) { return !(a == b); }

 private:
  uint64_t words_[2] = {0, 0};
};

}  // namespace irfarm

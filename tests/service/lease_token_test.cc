// LeaseToken (coordinator/lease_token.h): 16 bytes on the wire and back, every one of the 128
// bits compared, malformed lengths refused, and tokens that look like uniform random bits.
#include "coordinator/lease_token.h"

#include <gtest/gtest.h>

#include <bitset>
#include <set>
#include <string>

namespace irfarm {
namespace {

TEST(LeaseTokenTest, RoundTripsThroughItsSixteenBytes) {
  const LeaseToken t = LeaseToken::Random();
  EXPECT_FALSE(t.empty());
  const std::string bytes = t.Bytes();
  ASSERT_EQ(bytes.size(), LeaseToken::kBytes);
  const std::optional<LeaseToken> back = LeaseToken::FromBytes(bytes);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(*back, t);
}

TEST(LeaseTokenTest, EveryBitCounts) {
  const LeaseToken t = LeaseToken::Random();
  for (int bit = 0; bit < 128; ++bit) {
    std::string bytes = t.Bytes();
    bytes[size_t(bit / 8)] = char(bytes[size_t(bit / 8)] ^ (1 << (bit % 8)));
    const std::optional<LeaseToken> forged = LeaseToken::FromBytes(bytes);
    ASSERT_TRUE(forged.has_value());
    EXPECT_NE(*forged, t) << "bit " << bit;
  }
  EXPECT_NE(LeaseToken(), t);
}

TEST(LeaseTokenTest, OtherLengthsAreRefused) {
  const std::string bytes = LeaseToken::Random().Bytes();
  for (size_t n : {size_t(0), size_t(8), size_t(15), size_t(17), size_t(32)})
    EXPECT_FALSE(LeaseToken::FromBytes(std::string(n, 'x')).has_value()) << n;
  EXPECT_FALSE(LeaseToken::FromBytes(bytes + "x").has_value());
  EXPECT_FALSE(LeaseToken::FromBytes(bytes.substr(0, 8)).has_value());  // a 64-bit id
}

// 256 tokens: all distinct, and their 32768 bits about half ones. A source of only 64 random bits
// per token (the rest constant) gives 16384 +- 64 or 24576 +- 64 ones, a counter far fewer; the
// bounds are 6 sigma (sigma = sqrt(32768) / 2 = 90.5) of fair bits, so a working CSPRNG fails
// this with probability about 2e-9.
TEST(LeaseTokenTest, TokensAreDistinctAndLookUniform) {
  std::set<std::string> seen;
  size_t ones = 0;
  for (int i = 0; i < 256; ++i) {
    const std::string bytes = LeaseToken::Random().Bytes();
    seen.insert(bytes);
    for (char c : bytes) ones += std::bitset<8>(uint8_t(c)).count();
  }
  EXPECT_EQ(seen.size(), 256u);
  EXPECT_NEAR(double(ones), 16384.0, 6 * 90.5);
}

}  // namespace
}  // namespace irfarm

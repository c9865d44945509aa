// The random streams (Rng's stream argument) of the passes that touch a pixel: each pass draws
// from its own, so a pass added or changed leaves the numbers of the others as they were.
#pragma once

#include <cstdint>

namespace irfarm {

enum RenderStream : uint64_t {
  kStreamFinal = 1,
  kStreamOverture = 2,
  kStreamCacheCheck = 3,
  kStreamPilot = 4,
  kStreamSamplingCheck = 5,
  kStreamPathPilot = 6
};

}  // namespace irfarm

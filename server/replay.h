// Re-runs a recording (server/recording.h) offline: the starting snapshot, each command applied
// at the step it was applied live (through the same WorldCommands), the world stepped between,
// and every recorded state hash compared with the replayed world's.
#pragma once
#include <cstdint>
#include <string>

#include "server/recording.h"

namespace cellphys::server {

struct ReplayResult {
  uint64_t steps = 0, commands = 0, hashes_checked = 0;
  uint64_t final_step = 0, final_hash = 0;
  bool matched = true;            // every hash equal
  uint64_t mismatch_step = 0;     // the first that is not
  uint64_t recorded_hash = 0, replayed_hash = 0;
  std::string refused;            // a recorded command the replay refused (the recording does not fit this build)
};

ReplayResult replay(const Recording& r);

}  // namespace cellphys::server

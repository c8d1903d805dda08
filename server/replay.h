// Re-runs a recording (server/recording.h) offline: the starting snapshot, each command applied
// at the step it was applied live (through the same WorldCommands), the world stepped between,
// every recorded state hash compared with the replayed world's, and every recorded frame (the
// state messages the server sent: joins, ticks and their stages) compared byte for byte with the
// messages the replayed world gives (server/watcher_stream.h), but for the wall times the server
// measured (a tick's step_ms, the stages' ms), which are taken from the recording.
#pragma once
#include <cstdint>
#include <functional>
#include <string>

#include "runtime/ppe/world.h"
#include "server/recording.h"

namespace cellphys::server {

struct ReplayResult {
  uint64_t steps = 0, commands = 0, hashes_checked = 0;
  uint64_t frames_checked = 0, stages_checked = 0;  // joins and ticks; the stages messages after them
  uint64_t debug_checked = 0;                       // their debug messages (`--record-debug on`)
  uint64_t final_step = 0, final_hash = 0;
  bool matched = true;            // every hash and frame equal
  uint64_t mismatch_step = 0;     // the first that is not
  uint64_t recorded_hash = 0, replayed_hash = 0;  // a hash that differs
  std::string frame_difference;   // a frame that differs: which message, where and how
  std::string refused;            // a recorded command the replay refused (the recording does not fit this build)
};

/// `on_step`, when given, sees the world once before the first step and after every step.
ReplayResult replay(const Recording& r, const std::function<void(const ppe::World&)>& on_step = {});

}  // namespace cellphys::server

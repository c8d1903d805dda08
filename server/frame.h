// One published state of a world: what a room's thread hands to its clients after a tick in
// which something changed. Immutable once published and shared by every client, which each
// encode from it what their interest asks for (server/state_encoder.h), on the network's threads.
#pragma once
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "runtime/ppe/body_state.h"
#include "server/protocol.h"

namespace cellphys::server {

struct FrameBody {
  uint32_t id = 0, shape = 0;
  float scale = 1.0f;
  uint32_t flags = 0;  // protocol::kBodyAwake, kBodyStatic
  ppe::BodyState state;
  uint64_t changed = 0;  // the seq of the frame in which its state last changed (flags alone are not a move)
};

struct Frame {
  std::string world;
  uint64_t seq = 0;  // publication number, from 1
  uint64_t step = 0;
  uint32_t epoch = 0;
  bool paused = false;
  float dt = 0, tick_hz = 0;
  uint64_t state_hash = 0;
  protocol::TickStats stats{};
  std::vector<FrameBody> bodies;  // ascending id
  // The join's shape dictionary section (ShapeRecords, and the vertices and faces of hulls,
  // meshes and height fields), the same for a whole epoch.
  std::shared_ptr<const std::vector<unsigned char>> shapes;
  uint32_t num_shapes = 0;
  // The stages message of the step (server/stages_encoder.h), for the clients that ask for it.
  std::shared_ptr<const std::vector<unsigned char>> stages;
  // The debug message (server/debug_encoder.h), when some client of the room asked for it.
  std::shared_ptr<const std::vector<unsigned char>> debug;

  // Ticks encoded for clients that watch every body and are up to date to frame `from`: all such
  // clients get the same bytes, so they are encoded once (but for the `skipped` field).
  struct Encoded {
    uint64_t from;
    bool quantised;
    std::shared_ptr<const std::vector<unsigned char>> bytes;
  };
  mutable std::mutex cache_mutex;
  mutable std::vector<Encoded> cache;
};

}  // namespace cellphys::server

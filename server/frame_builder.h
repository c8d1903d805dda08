// A published Frame from a world: every body's state, with the frame at which its state last
// changed (found against the previous frame of the same epoch). The room builds one after each
// tick in which something changed; `cellphys replay` builds the same to check a recording.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"
#include "server/frame.h"

namespace cellphys::server {

/// What a frame says besides the world's bodies.
struct FrameContext {
  std::string world;
  uint64_t seq = 0;  // this frame's publication number
  uint32_t epoch = 0;
  bool paused = false;
  float tick_hz = 0;     // 0: as fast as it can
  double step_ms = 0;    // wall time of the last step
  std::shared_ptr<const std::vector<unsigned char>> shapes;  // encode_shapes(world.shapes())
};

/// `prev` (or null) is the frame published before this one.
std::shared_ptr<Frame> build_frame(const ppe::World& w, const FrameContext& at, const Frame* prev);

}  // namespace cellphys::server

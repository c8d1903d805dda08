// How a served world is stepped, as the commands pause, resume, step_once and reset leave it:
// paused or running, one step asked for, and the epoch (one more at every reset). The room and
// `cellphys replay` both keep one, so a replayed frame carries the paused flag and epoch the
// live one did.
#pragma once
#include <cstdint>

#include "server/protocol.h"

namespace cellphys::server {

struct PlayState {
  bool paused = false, step_once = false;
  uint32_t epoch = 0;

  /// After an applied command; true when the world's running state changed (clients are told).
  bool applied(uint16_t type) {
    using protocol::Type;
    switch (static_cast<Type>(type)) {
      case Type::pause: {
        const bool changed = !paused;
        paused = true;
        return changed;
      }
      case Type::resume: {
        const bool changed = paused;
        paused = false;
        step_once = false;
        return changed;
      }
      case Type::step_once: step_once = true; return false;
      case Type::reset: ++epoch; return true;
      default: return false;
    }
  }
  /// Whether the next tick steps the world.
  bool steps() const { return !paused || step_once; }
  /// After a step: a single step leaves the world paused.
  void stepped() {
    if (step_once) {
      step_once = false;
      paused = true;
    }
  }
};

}  // namespace cellphys::server

#include "server/protocol.h"

namespace cellphys::server::protocol {

const char* type_name(uint16_t type) {
  switch (static_cast<Type>(type)) {
    case Type::join: return "join";
    case Type::tick: return "tick";
    case Type::ack: return "ack";
    case Type::error: return "error";
    case Type::status: return "status";
    case Type::debug: return "debug";
    case Type::stages: return "stages";
    case Type::subscribe: return "subscribe";
    case Type::spawn: return "spawn";
    case Type::remove: return "remove";
    case Type::impulse: return "impulse";
    case Type::drag_start: return "drag_start";
    case Type::drag_move: return "drag_move";
    case Type::drag_release: return "drag_release";
    case Type::pause: return "pause";
    case Type::resume: return "resume";
    case Type::step_once: return "step_once";
    case Type::reset: return "reset";
    case Type::set_speed: return "set_speed";
  }
  return "";
}

}  // namespace cellphys::server::protocol

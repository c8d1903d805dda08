// A world and the commands clients may give it: each is checked against the world (every field,
// with the field named when refused) before anything changes, then applied. The live server
// (server/room.h) and `cellphys replay` both go through this class, so a recording's commands
// do the same to the replayed world as they did to the live one.
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "runtime/ppe/world.h"
#include "server/command.h"

namespace cellphys::server {

/// Bounds on what a command may ask (docs/protocol.md): beyond them a world would be thrown
/// about, or grow without end.
struct CommandLimits {
  uint32_t max_bodies = 20000;
  float max_speed = 100.0f;         // m/s: a spawned body's speed, and the speed an impulse may add
  float max_angular_speed = 100.0f; // rad/s: a spawned body's
  uint32_t max_drags = 256;
  float max_drag_stiffness_per_kg = 1e5f;  // N/m per kg of the body
};

/// What applying a command did.
struct Applied {
  uint32_t result = 0;  // spawn: the body's id; drag_start: the drag's id
  bool reset = false;   // the world was replaced by its starting snapshot
};

class WorldCommands {
 public:
  /// The world starts from `initial` (World::snapshot() bytes), which reset returns to.
  explicit WorldCommands(std::vector<unsigned char> initial, CommandLimits limits = {});

  ppe::World& world() { return *world_; }
  const ppe::World& world() const { return *world_; }
  const std::vector<unsigned char>& initial_snapshot() const { return initial_; }

  /// Why `c` cannot be applied now (its field and reason), or nothing. pause, resume and
  /// step_once are always admitted: they concern the stepping, which is the caller's.
  std::optional<CommandError> check(const Command& c) const;
  /// Applies `c`, which check() admitted; a world that still refuses it (WorldError) leaves
  /// the world as it was and the error comes back as a CommandError.
  std::optional<CommandError> apply(const Command& c, Applied& out);

 private:
  struct Drag {
    bool alive = false;
    ppe::BodyId body = 0;
    ppe::ForceId force = 0;
    float point_body[3] = {};
    float stiffness = 0, damping = 0;
  };
  std::optional<CommandError> check_drag(const char* type, uint32_t drag) const;
  ppe::ForceId add_drag_force(const Drag& d, const float target[3]);

  std::vector<unsigned char> initial_;
  CommandLimits limits_;
  std::unique_ptr<ppe::World> world_;
  std::vector<Drag> drags_;
};

}  // namespace cellphys::server

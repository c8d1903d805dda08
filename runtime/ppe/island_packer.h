// Pack: an island's bodies, contacts and forces (or a part of a decoupled island, with the
// bodies across its cuts as kinematic ghosts) into the bytes a compute kernel takes; unpack
// results into the world.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/body_records.h"

namespace cellphys::ppe {

struct WorldSettings;

struct IslandContent {
  std::vector<uint32_t> bodies;    // world ids, ascending
  std::vector<uint32_t> contacts;  // indices into the step's contacts
  std::vector<uint32_t> forces;    // world force ids
};

struct PackContext {
  const std::vector<WorldBody>& bodies;
  const std::vector<WorldForce>& forces;
  const std::vector<WorldContact>& contacts;
  const WorldSettings& settings;
  const std::vector<WorldBody>& start;  // the bodies at the start of the step
};

struct PackedIsland {
  std::vector<uint32_t> bodies;  // local index -> world id (ascending)
  std::vector<uint8_t> ghost;    // per local index: a kinematic copy of a body of another part
  std::vector<unsigned char> image;
  std::vector<unsigned char> result;
};

/// Packs one island or part from the start-of-step state (pc.start); ghosts (kinematic: no
/// force moves them) take their latest velocity from pc.bodies.
PackedIsland pack_island(const PackContext& pc, const IslandContent& part);

/// Copies a successful result's advanced bodies back into the world.
void unpack_island(const PackedIsland& p, std::vector<WorldBody>& bodies);

}  // namespace cellphys::ppe

// Pack: an island's bodies, contacts and forces into the bytes a compute kernel takes;
// decouple islands too big for a local store by cutting them in space; unpack results into
// the world. A coupling the cut crosses goes into both parts, each of which holds the body
// across the cut as a ghost, so both sides stay implicit in the coupling; see decouple().
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

/// The parts of an island that each fit the local store (just the island when it fits), in
/// the order they are integrated; counts the couplings cut. Integrating the parts in order,
/// each holding the bodies across its cuts as kinematic ghosts at their latest velocities, is
/// one block Gauss-Seidel sweep on the island's linear system; sweeps repeat until the
/// velocities settle (World::step), so the parts converge on the whole island's step.
std::vector<IslandContent> decouple(const PackContext& pc, IslandContent island, uint32_t& cut_couplings);

/// Packs one island or part from the start-of-step state (pc.start); ghosts (kinematic: no
/// force moves them) take their latest velocity from pc.bodies.
PackedIsland pack_island(const PackContext& pc, const IslandContent& part);

/// Copies a successful result's advanced bodies back into the world.
void unpack_island(const PackedIsland& p, std::vector<WorldBody>& bodies);

}  // namespace cellphys::ppe

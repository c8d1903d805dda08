// Pack: an island's bodies, contacts and forces into the bytes a compute kernel takes;
// decouple islands too big for a local store by cutting them in space; unpack results into
// the world. A coupling the cut crosses goes into both parts, each of which holds the body
// across the cut as a kinematic ghost (infinite mass, moving with its start-of-step
// velocity): both sides stay implicit in the coupling, so a stiff contact across the cut is
// as stable as one against a moving wall.
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
  const std::vector<WorldBody>& start;  // the bodies at the start of the step (ghost poses)
};

struct PackedIsland {
  std::vector<uint32_t> bodies;  // local index -> world id (ascending)
  std::vector<uint8_t> ghost;    // per local index: a kinematic copy of a body of another part
  std::vector<unsigned char> image;
  std::vector<unsigned char> result;
};

/// The parts of an island that each fit the local store (just the island when it fits), in
/// the order they are integrated; counts the couplings cut. The parts run one after another
/// (Gauss-Seidel across the cut): a part sees the ghosts of parts integrated before it moving
/// with their new velocities, so a cut coupling is never resolved twice over in one step.
std::vector<IslandContent> decouple(const PackContext& pc, IslandContent island, uint32_t& cut_couplings);

/// Packs one island or part. Ghosts take their pose from pc.start and their velocity from
/// pc.bodies (the new one when their part has been integrated already this step).
PackedIsland pack_island(const PackContext& pc, const IslandContent& part);

/// Copies a successful result's advanced bodies back into the world.
void unpack_island(const PackedIsland& p, std::vector<WorldBody>& bodies);

}  // namespace cellphys::ppe

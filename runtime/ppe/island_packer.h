// Pack: an island's bodies, contacts and forces into the bytes a compute kernel takes;
// decouple islands too big for a local store by cutting them in space, applying the cut
// couplings explicitly from the start-of-step state; unpack results into the world.
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
};

struct PackedIsland {
  std::vector<uint32_t> bodies;  // local index -> world id
  std::vector<unsigned char> image;
  std::vector<unsigned char> result;
};

/// Packs the island, split into parts that each fit the local store when it does not;
/// appends the parts to `out` and counts the couplings cut.
void pack_decoupled(const PackContext& pc, IslandContent island, std::vector<PackedIsland>& out, uint32_t& cut_couplings);

/// Copies a successful result's advanced bodies back into the world.
void unpack_island(const PackedIsland& p, std::vector<WorldBody>& bodies);

}  // namespace cellphys::ppe

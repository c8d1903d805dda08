// Pack: an island's bodies, contacts and forces (or a part of a decoupled island, with the
// bodies across its cuts as kinematic ghosts) into the bytes a compute kernel takes; unpack
// results into the world.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/spu/island_image.h"
#include "runtime/spu/workspace.h"

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
  bool sealed = true;  // image and result checksummed; false: stepped at once on the packing thread
};

/// What packing reuses from one island to the next. The world keeps one, so a warm step packs
/// its islands without allocating.
struct PackScratch {
  spu::IslandBuilder builder;
  std::vector<uint32_t> ghosts, jointed, contacts;
  std::vector<uint32_t> merged;            // the contacts' sort
  std::vector<uint64_t> keys, key_buffer;
  std::vector<unsigned char> instance;
  std::vector<int32_t> local;  // per world body: its index in the island being packed; -2 outside it
};

/// Orders `cs`, indices into `contacts`, by (body a, body b, index): each pair's contacts
/// together, in the fixed order the image lists them.
void sort_contacts_by_pair(const std::vector<WorldContact>& contacts, std::vector<uint32_t>& cs, PackScratch& scratch);

/// Packs one island or part from the start-of-step state (pc.start) into `out` (replaced; its
/// storage is reused); ghosts (kinematic: no force moves them) take their latest velocity from
/// pc.bodies.
/// Every scratch grown to the largest of them: after a step has packed each island on some
/// thread, any thread packs any of them without allocating (which thread takes which island
/// varies from step to step).
void match_capacities(std::vector<PackScratch>& scratches);

void pack_island(const PackContext& pc, const IslandContent& part, PackScratch& scratch, PackedIsland& out,
                 bool seal = true);

/// Counts at least those of the image of an island of `bodies` bodies (ghosts included),
/// `contacts` contacts, other forces of `force_bytes` instance bytes and `couplings` of its
/// bodies to each other (contacts or forces; each two off-diagonal blocks): every body given a
/// damping and a gyroscopic instance, every section its alignment, every scratch the largest
/// kernel's. The footprint grows with each count, so a content under the bound needs no
/// packing to know it fits.
spu::IslandCounts counts_at_least(const WorldSettings& s, size_t bodies, size_t contacts, size_t force_bytes,
                                  size_t couplings);

/// Copies a successful result's advanced bodies back into the world.
void unpack_island(const PackedIsland& p, std::vector<WorldBody>& bodies);

}  // namespace cellphys::ppe

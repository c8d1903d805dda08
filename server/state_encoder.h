// State out: a world's shape dictionary, and a published Frame encoded for one client's interest
// as a join (everything it watches) or a tick (what changed since the frame it last got).
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

#include "runtime/ppe/shapes.h"
#include "server/frame.h"

namespace cellphys::server {

/// What a client watches (protocol::Subscribe): every body, or those whose centre is in a box
/// (planes always), at full precision or quantised.
struct Interest {
  bool quantised = false;
  bool region = false;
  bool debug = false;  // a debug message after every tick (protocol revision 2)
  bool stages = false; // a stages message after every tick (protocol revision 3)
  float min[3] = {}, max[3] = {};
  bool contains(const FrameBody& b) const;
};

/// The join's shape-dictionary section: one ShapeRecord per shape, hulls, meshes and height
/// fields followed by their vertices and faces, compounds by their parts.
std::vector<unsigned char> encode_shapes(const ppe::ShapeDictionary& shapes);

/// The lowest protocol revision a client must read to read a join of this dictionary
/// (protocol::shape_revision of its shapes): 4 with a mesh, a height field or a compound, else 1;
/// and the first shape that needs it, to name it to a client that reads less.
struct RevisionNeed {
  uint32_t revision = 1;
  uint32_t shape = 0;
  spu::ShapeType type = spu::ShapeType::sphere;
};
RevisionNeed revision_needed(const ppe::ShapeDictionary& shapes);

/// Appends a join message for `f`; `known` becomes the ids of the bodies it carries.
void encode_join(const Frame& f, const Interest& in, bool can_command, std::vector<uint32_t>& known,
                 std::vector<unsigned char>& out);

/// Appends a tick message: bodies in the interest the client does not hold (entered), held ones
/// whose state changed after frame `since` (moved), held ones removed or out of the interest
/// (gone). `known` (ascending ids the client holds) becomes the ids it holds after this message.
void encode_tick(const Frame& f, const Interest& in, uint64_t since, uint32_t skipped, std::vector<uint32_t>& known,
                 std::vector<unsigned char>& out);

/// encode_tick for a client watching every body whose `known` is the body set of frame `since`:
/// such clients all get the same bytes, encoded once per (since, precision) and kept in the
/// frame. `skipped` is 0 in the shared bytes.
std::shared_ptr<const std::vector<unsigned char>> shared_tick(const Frame& f, bool quantised, uint64_t since,
                                                              std::vector<uint32_t>& known);

/// Sets the `skipped` field of an encoded tick.
void set_skipped(std::vector<unsigned char>& tick, uint32_t skipped);

}  // namespace cellphys::server

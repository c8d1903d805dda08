#include "server/debug_encoder.h"

#include <algorithm>
#include <cstring>

#include "server/protocol.h"

namespace cellphys::server {

namespace {

template <class T>
void put(std::vector<unsigned char>& out, const T& v) {
  const size_t at = out.size();
  out.resize(at + sizeof(T));
  std::memcpy(out.data() + at, &v, sizeof(T));
}

}  // namespace

std::vector<unsigned char> encode_debug(const ppe::World& w, uint32_t epoch) {
  using namespace protocol;
  const std::vector<ppe::BodyId> ids = w.bodies();
  const std::vector<ppe::DebugContact> contacts = w.debug_contacts();
  const std::vector<ppe::CutCoupling>& cuts = w.cut_couplings();
  Debug d{};
  d.header = Header{0, static_cast<uint16_t>(Type::debug), kVersion};
  d.step = w.last_stats().step;
  d.epoch = epoch;
  d.num_contacts = static_cast<uint32_t>(contacts.size());
  d.num_cuts = static_cast<uint32_t>(cuts.size());
  std::vector<unsigned char> out;
  out.reserve(sizeof d + ids.size() * sizeof(DebugBody) + contacts.size() * sizeof(protocol::DebugContact) +
              cuts.size() * sizeof(DebugCut));
  put(out, d);
  uint32_t n = 0;
  for (ppe::BodyId id : ids) {
    if (w.is_static(id)) continue;
    DebugBody b{};
    b.id = id;
    b.island = w.last_island(id);
    b.mass = w.mass(id);
    b.flags = b.island != kNoIsland && w.island_decoupled(b.island) ? kIslandDecoupled : 0u;
    put(out, b);
    ++n;
  }
  for (const ppe::DebugContact& c : contacts) {
    protocol::DebugContact r{};
    r.a = c.a;
    r.b = c.b;
    std::copy(c.point, c.point + 3, r.point);
    std::copy(c.normal, c.normal + 3, r.normal);
    r.depth = c.depth;
    r.force = c.force;
    put(out, r);
  }
  for (const ppe::CutCoupling& c : cuts) {
    DebugCut r{};
    r.a = c.a;
    r.b = c.b;
    r.force = c.force;
    r.island = c.island;
    std::copy(c.point, c.point + 3, r.point);
    put(out, r);
  }
  const uint32_t length = static_cast<uint32_t>(out.size());
  std::memcpy(out.data() + offsetof(Debug, header), &length, 4);
  std::memcpy(out.data() + offsetof(Debug, num_bodies), &n, 4);
  return out;
}

}  // namespace cellphys::server

#include "runtime/ppe/result_check.h"

#include <cstring>

#include "runtime/spu/island_image.h"

namespace cellphys::ppe {

using namespace cellphys::gen;

bool sound_result(const PackedIsland& p, const spu::IslandReport& r) {
  const uint32_t n = static_cast<uint32_t>(p.bodies.size());
  Island_Result h;
  if (p.result.size() < sizeof h) return false;
  std::memcpy(&h, p.result.data(), sizeof h);
  if (h.magic != spu::kResultMagic || h.num_bodies != n || h.status != static_cast<uint32_t>(r.status)) return false;
  switch (r.status) {
    case spu::IslandStatus::does_not_fit: return true;
    case spu::IslandStatus::malformed: return false;
    case spu::IslandStatus::ok:
    case spu::IslandStatus::failed: break;
  }
  if (h.total_bytes != spu::result_bytes(n) || p.result.size() != h.total_bytes) return false;
  const size_t head = spu::align16(sizeof(Island_Result)), steps = size_t{n} * sizeof(Rigid_Body_Step);
  if (!p.sealed) return true;  // stepped on this thread from its own packing: nothing to check
  const unsigned char* base = p.result.data();
  return spu::image_checksum(base + head + steps, size_t{n} * sizeof(Rigid_Body), spu::image_checksum(base + head, steps)) == h.checksum;
}

}  // namespace cellphys::ppe

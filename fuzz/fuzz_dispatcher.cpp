// libFuzzer target for what the dispatcher decodes from a compute node: the first byte picks a
// built-in scene (fuzz/wire_loopback.h), the rest is the node's answer to the scene's first
// wave, sealed again (header and record checksums) so mutations reach the results. The world
// takes what is sound and recomputes the rest: whatever the bytes, it steps, and every body's
// state is finite after it (nothing crashes under ASan/UBSan).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "fuzz/seal.h"
#include "fuzz/wire_loopback.h"

namespace {

bool finite(const float* p, int n) {
  for (int k = 0; k < n; ++k)
    if (!std::isfinite(p[k])) return false;
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace cellphys;
  static const std::vector<std::vector<unsigned char>> worlds = [] {
    std::vector<std::vector<unsigned char>> v;
    for (const char* name : fuzz::kWireScenes) v.push_back(fuzz::scene_snapshot(name));
    return v;
  }();
  if (size < 1) return 0;
  const std::vector<unsigned char>& snap = worlds[data[0] % worlds.size()];
  std::vector<unsigned char> answer(data + 1, data + size);
  fuzz::seal_results(answer);
  auto w = ppe::World::restore(snap.data(), snap.size());
  w->set_runner(std::make_shared<fuzz::WireLoopback>(
      [&](const std::vector<unsigned char>&, std::vector<unsigned char>& out) { out = answer; }));
  w->step();
  for (ppe::BodyId id : w->bodies()) {
    const ppe::BodyState s = w->state(id);
    if (!finite(s.position, 3) || !finite(s.orientation, 4) || !finite(s.velocity, 3) || !finite(s.angular_velocity, 3))
      __builtin_trap();
  }
  return 0;
}

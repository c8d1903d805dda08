// libFuzzer target for the snapshot reader (World::restore): the bytes are sealed again (size
// and checksum) so mutations reach the records. Any bytes either restore or raise WorldError;
// a restored world saves bytes that restore to a world saving the same bytes, and a small one
// steps (nothing crashes under ASan/UBSan; one step, since a hard one halves its step size
// many times and takes a second under the sanitizers).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "fuzz/seal.h"
#include "runtime/ppe/world.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using cellphys::ppe::World;
  std::vector<unsigned char> b(data, data + size);
  cellphys::fuzz::seal_snapshot(b);
  std::unique_ptr<World> w;
  try {
    w = World::restore(b.data(), b.size());
  } catch (const cellphys::ppe::WorldError&) {
    return 0;
  }
  // Saved again, the bytes are canonical (settings in table order, pairs in key order).
  const std::vector<unsigned char> once = w->snapshot();
  std::unique_ptr<World> again;
  try {
    again = World::restore(once.data(), once.size());
  } catch (const cellphys::ppe::WorldError&) {
    __builtin_trap();  // what a world saves must restore
  }
  if (again->snapshot() != once) __builtin_trap();
  if (w->num_bodies() <= 64) {
    auto s = w->settings();
    s.workers = 1;  // no threads per input
    w->set_settings(s);
    w->step();
  }
  return 0;
}

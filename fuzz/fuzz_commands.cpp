// libFuzzer target for the server's command decoder and checks: the input is a run of client
// messages, each framed by its own header length, applied to a small world between steps as a
// room would. Whatever the bytes, framing and checks must refuse cleanly, and what they admit
// must leave a world that steps.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>

#include "server/world_commands.h"

namespace {

std::vector<unsigned char> small_world() {
  cellphys::ppe::World w;
  const float n[3] = {0, 0, 1}, h[3] = {0.5f, 0.5f, 0.5f};
  const uint32_t ground = w.shapes().add_plane(n, 0), box = w.shapes().add_box(h), ball = w.shapes().add_sphere(0.3f);
  cellphys::ppe::BodyDesc d;
  d.shape = ground;
  d.is_static = true;
  w.add_body(d);
  d = cellphys::ppe::BodyDesc{};
  d.mass = 1;
  d.shape = box;
  d.state.position[2] = 0.5f;
  w.add_body(d);
  d.shape = ball;
  d.state.position[2] = 2;
  w.add_body(d);
  return w.snapshot();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::vector<unsigned char> initial = small_world();
  cellphys::server::WorldCommands cmds(initial);
  size_t at = 0, steps = 0;
  while (size - at >= 4 && steps < 4) {
    uint32_t length;
    std::memcpy(&length, data + at, 4);
    const size_t n = std::min<size_t>(std::max<uint32_t>(length, 1), size - at);
    cellphys::server::Command c;
    cellphys::server::CommandError err;
    if (cellphys::server::decode_client_message(data + at, n, c, err) && c.changes_world()) {
      cellphys::server::Applied a;
      if (!cmds.apply(c, a) && c.type == static_cast<uint16_t>(cellphys::server::protocol::Type::step_once)) {
        cmds.world().step();
        ++steps;
      }
    }
    at += n;
  }
  cmds.world().step();
  return 0;
}

// libFuzzer target for the scene reader: any bytes either parse or raise SceneError (nothing
// else escapes, nothing crashes under ASan/UBSan); what parses writes back to text that parses
// to an equal scene; and small scenes build into a World or raise SceneError.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "runtime/scene/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace cellphys::scene;
  const std::string text(reinterpret_cast<const char*>(data), size);
  SceneDesc d;
  try {
    d = parse_scene(text, "fuzz.json");
  } catch (const SceneError&) {
    return 0;
  }
  const std::string written = write_scene(d);
  SceneDesc again;
  try {
    again = parse_scene(written, "written.json");
  } catch (const SceneError& e) {
    __builtin_trap();  // what the writer wrote must read back
  }
  if (!(again == d)) __builtin_trap();
  size_t hull_points = 0;
  for (const ShapeSpec& s : d.shapes) hull_points += s.points.size() / 3;
  if (d.bodies.size() <= 64 && hull_points <= 512) {
    try {
      BuiltScene b = build_world(d);
      (void)b;
    } catch (const SceneError&) {
    }
  }
  return 0;
}

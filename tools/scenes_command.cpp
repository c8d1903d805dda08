// `cellphys scenes`: the built-in scenes, one line each, name and description.
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "runtime/scene/scene.h"
#include "tools/builtin_scenes.h"
#include "tools/cli.h"

namespace cellphys::cli {

int scenes_main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::puts("usage: cellphys scenes\n\nLists the built-in scenes (name and description); run one with "
                "`cellphys run NAME`.");
      return 0;
    }
    std::fprintf(stderr, "cellphys scenes: unexpected argument '%s'\n", a.c_str());
    return 2;
  }
  const std::vector<BuiltinScene> all = builtin_scenes();
  if (all.empty()) {
    std::fprintf(stderr, "cellphys scenes: no built-in scenes found (set CELLPHYS_SCENES)\n");
    return 1;
  }
  size_t width = 0;
  for (const BuiltinScene& b : all) width = std::max(width, b.name.size());
  int rc = 0;
  for (const BuiltinScene& b : all) {
    try {
      const scene::SceneDesc d = scene::load_scene(b.path);
      std::printf("%-*s  %s%s\n", static_cast<int>(width), b.name.c_str(), d.description.c_str(),
                  b.name == kDefaultScene ? " (default)" : "");
    } catch (const scene::SceneError& e) {
      std::fprintf(stderr, "cellphys: %s\n", e.what());
      rc = 1;
    }
  }
  return rc;
}

}  // namespace cellphys::cli

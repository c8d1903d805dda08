// The built-in scenes (examples/scenes/*.json): where they are looked up, their names, and the
// file a `cellphys run SCENE` argument names.
#pragma once
#include <string>
#include <vector>

namespace cellphys::cli {

// The scene `cellphys run` steps when given none.
inline constexpr char kDefaultScene[] = "world1000";

struct BuiltinScene {
  std::string name, path;
};

// Directories searched, in order: $CELLPHYS_SCENES alone when set; else next to the executable
// (installed, or build/<preset>/tools/ in a source tree), then the source tree it was built from.
std::vector<std::string> scene_dirs();

// The scenes of the first of scene_dirs() that has any: the default first, then by name.
std::vector<BuiltinScene> builtin_scenes();

// The file a SCENE argument names (a path, or a built-in scene's file); throws UsageError
// listing the built-in scenes when it names neither.
std::string resolve_scene(const std::string& arg);

}  // namespace cellphys::cli

#include "tools/builtin_scenes.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>

#include "tools/usage_error.h"

#ifndef CELLPHYS_SCENES_DIR
#define CELLPHYS_SCENES_DIR ""
#endif

namespace cellphys::cli {

namespace {

namespace fs = std::filesystem;

std::string exe_dir() {
  std::error_code ec;
  const fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? std::string() : p.parent_path().string();
}

bool looks_like_path(const std::string& s) {
  return s.find('/') != std::string::npos || (s.size() > 5 && s.compare(s.size() - 5, 5, ".json") == 0);
}

}  // namespace

std::vector<std::string> scene_dirs() {
  std::vector<std::string> dirs;
  if (const char* env = std::getenv("CELLPHYS_SCENES"); env && *env) {
    dirs.push_back(env);
    return dirs;  // an explicit override is the only place looked at
  }
  const std::string exe = exe_dir();
  if (!exe.empty()) {
    dirs.push_back(exe + "/scenes");                         // an installed layout
    dirs.push_back((fs::path(exe) / "../../../examples/scenes").lexically_normal().string());  // build/<preset>/tools/
  }
  if (*CELLPHYS_SCENES_DIR) dirs.push_back(CELLPHYS_SCENES_DIR);  // the source tree it was built from
  return dirs;
}

std::vector<BuiltinScene> builtin_scenes() {
  for (const std::string& d : scene_dirs()) {
    std::error_code ec;
    if (!fs::is_directory(d, ec)) continue;
    std::vector<BuiltinScene> out;
    for (const auto& e : fs::directory_iterator(d, ec))
      if (e.path().extension() == ".json") out.push_back({e.path().stem().string(), e.path().string()});
    if (out.empty()) continue;
    std::sort(out.begin(), out.end(), [](const BuiltinScene& a, const BuiltinScene& b) {
      // the default world first, then by name
      if ((a.name == kDefaultScene) != (b.name == kDefaultScene)) return a.name == kDefaultScene;
      return a.name < b.name;
    });
    return out;
  }
  return {};
}

std::string resolve_scene(const std::string& arg) {
  std::error_code ec;
  if (looks_like_path(arg) || fs::is_regular_file(arg, ec)) return arg;
  const std::vector<BuiltinScene> all = builtin_scenes();
  for (const BuiltinScene& b : all)
    if (b.name == arg) return b.path;
  std::string names;
  for (const BuiltinScene& b : all) names += (names.empty() ? "" : ", ") + b.name;
  if (names.empty()) {
    std::string where;
    for (const std::string& d : scene_dirs()) where += (where.empty() ? "" : ", ") + d;
    throw UsageError{"unknown scene '" + arg + "': no built-in scenes found (looked in " + where +
                     "; set CELLPHYS_SCENES)"};
  }
  throw UsageError{"unknown scene '" + arg + "' (not a file; built-in scenes: " + names + ")"};
}

}  // namespace cellphys::cli

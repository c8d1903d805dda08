// Every field of WorldSettings declared once, in one table: its name, its place in a scene
// file's "settings", its type, its bounds and what it means. The World's validation, the
// scene reader, writer and equality, and snapshots iterate the table; the forces' globals
// join it from the generated gen::kGlobalTable, so a new force's global needs no C++ here.
// A field's default is its initialiser in WorldSettings.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"

namespace cellphys::ppe {

/// Limits of the settings (the kernel's own are spu::kMaxHalvings and LocalStore::kMaxCapacity).
inline constexpr int kMaxWorkers = 256;
inline constexpr uint32_t kMaxDecoupleSweeps = 64;
inline constexpr size_t kMinLocalStoreBytes = 16 * 1024;

/// A field's C++ type in WorldSettings, and so its form in a scene file and a snapshot.
enum class SettingType {
  f32,         // float: a number
  vec3,        // float[3]: [x, y, z]
  u32,         // uint32_t: an integer
  i32,         // int: an integer
  size,        // size_t: an integer
  boolean,     // bool: true or false
  integrator,  // spu::Integrator: its name
  solver,      // spu::Solver: its name
};

/// Bounds of a number (a float must also be finite): a lower one, inclusive or not, and an upper one.
struct Bounds {
  bool has_min = false, min_exclusive = false, has_max = false;
  double min = 0, max = 0;
};

struct Setting {
  std::string name;  ///< the WorldSettings member: "dt", "globals.contact_slop"
  std::string path;  ///< its place under a scene file's settings: "dt", "contact.slop"
  SettingType type;
  size_t offset;     ///< of the member in WorldSettings
  Bounds bounds;
  std::string doc;
};

/// Every setting: the World's own, then the forces' globals.
const std::vector<Setting>& settings_table();
/// The setting at a scene path ("contact.slop"), or nullptr.
const Setting* find_setting(const std::string& path);

/// The member a setting describes, of the C++ type its SettingType names.
void* field_of(WorldSettings& s, const Setting& row);
const void* field_of(const WorldSettings& s, const Setting& row);

/// Why one number (a float lane or an integer) cannot be the value of `row` ("" when it can).
std::string value_problem(const Setting& row, double v);

/// Throws WorldError("settings.NAME: REASON") for the first setting outside its bounds.
void validate_settings(const WorldSettings& s);

}  // namespace cellphys::ppe

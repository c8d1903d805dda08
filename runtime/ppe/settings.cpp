#include "runtime/ppe/settings.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <type_traits>

#include "runtime/spu/local_store.h"

namespace cellphys::ppe {

namespace {

static_assert(std::is_standard_layout_v<WorldSettings>, "the table addresses WorldSettings' members by offset");
// WorldSettings' members by type, in order: a member added there and not here (nor to the
// table below) fails this, for any force set's globals.
struct SettingsShape {
  float dt;
  gen::Force_Globals globals;
  spu::Integrator integrator;
  spu::Solver solver;
  float tolerance;
  uint32_t max_halvings;
  bool sleeping;
  int workers;
  float contact_margin, contact_load_depth, contact_joined_hold_depth, joint_projection;
  size_t local_store_bytes, whole_island_bytes;
  uint32_t decouple_sweeps;
  float decouple_tolerance, region_min[3], region_max[3], sleep_linear, sleep_angular, sleep_time;
};
static_assert(sizeof(WorldSettings) == sizeof(SettingsShape),
              "WorldSettings changed: a new member needs a row in the table below");

template <class T>
constexpr SettingType type_of();
template <> constexpr SettingType type_of<float>() { return SettingType::f32; }
template <> constexpr SettingType type_of<float[3]>() { return SettingType::vec3; }
template <> constexpr SettingType type_of<uint32_t>() { return SettingType::u32; }
template <> constexpr SettingType type_of<int>() { return SettingType::i32; }
template <> constexpr SettingType type_of<size_t>() { return SettingType::size; }
template <> constexpr SettingType type_of<bool>() { return SettingType::boolean; }
template <> constexpr SettingType type_of<spu::Integrator>() { return SettingType::integrator; }
template <> constexpr SettingType type_of<spu::Solver>() { return SettingType::solver; }

constexpr Bounds none() { return {}; }
constexpr Bounds at_least(double lo) { return {true, false, false, lo, 0}; }
constexpr Bounds above(double lo) { return {true, true, false, lo, 0}; }
constexpr Bounds between(double lo, double hi) { return {true, false, true, lo, hi}; }

// A row of WorldSettings member m: its name, type and offset from the member itself.
#define CELLPHYS_SETTING(m, path, bounds, doc) \
  Setting { #m, path, type_of<decltype(WorldSettings::m)>(), offsetof(WorldSettings, m), bounds, doc }

std::vector<Setting> world_settings() {
  return {
      CELLPHYS_SETTING(dt, "dt", above(0), "step (s)"),
      CELLPHYS_SETTING(integrator, "integrator", none(), "integration method (docs/integrators.md)"),
      CELLPHYS_SETTING(solver, "solver", none(), "linear solver of the implicit integrators"),
      CELLPHYS_SETTING(tolerance, "tolerance", above(0), "linear solver tolerance, relative and absolute"),
      CELLPHYS_SETTING(max_halvings, "max_halvings", between(0, spu::kMaxHalvings),
                       "a failed step is retried as two halves, at most this many times over"),
      CELLPHYS_SETTING(sleeping, "sleeping", none(), "islands at rest go to sleep"),
      CELLPHYS_SETTING(sleep_linear, "sleep.linear", at_least(0),
                       "an island sleeps when every body has been slower than this (m/s) ..."),
      CELLPHYS_SETTING(sleep_angular, "sleep.angular", at_least(0), "... and has turned slower than this (rad/s) ..."),
      CELLPHYS_SETTING(sleep_time, "sleep.time", at_least(0), "... for this long (s)"),
      CELLPHYS_SETTING(workers, "workers", between(1, kMaxWorkers), "compute worker threads"),
      CELLPHYS_SETTING(contact_margin, "contact.margin", at_least(0),
                       "contacts are generated for gaps up to the contact slop plus each body's reach in the step (dt "
                       "times its speed and the spin of its farthest point) plus this margin (m)"),
      CELLPHYS_SETTING(contact_load_depth, "contact.load_depth", above(0),
                       "a contact is stiffened to sink no deeper than this under the weight resting on it, so a light "
                       "body holds a heavy one (m)"),
      CELLPHYS_SETTING(contact_joined_hold_depth, "contact.joined_hold_depth", above(0),
                       "deepest overlap (m) the spring of a contact between two bodies joints join (directly or "
                       "through others) acts on: the push stage moves such bodies as one and cannot part them, so "
                       "this spring must push a limb out of its own torso (contact.hold_depth for the rest)"),
      CELLPHYS_SETTING(joint_projection, "joint.projection", at_least(0),
                       "a joint whose points a step leaves further apart than this is moved back to it, without "
                       "changing a velocity (m; 0: never)"),
      CELLPHYS_SETTING(local_store_bytes, "local_store_bytes",
                       between(double(kMinLocalStoreBytes), double(spu::LocalStore::kMaxCapacity)),
                       "a compute worker's local store (bytes)"),
      CELLPHYS_SETTING(whole_island_bytes, "whole_island_bytes", between(0, double(spu::LocalStore::kMaxCapacity)),
                       "an island too big for the local store but not for this is computed whole, in a store grown "
                       "to its size (by the in-process workers; compute nodes over MPI split it); a bigger one is "
                       "split into parts that fit the local store (bytes; 0: always split)"),
      CELLPHYS_SETTING(decouple_sweeps, "decouple.sweeps", between(1, kMaxDecoupleSweeps),
                       "an island split to fit the local store is swept (its parts integrated in order) until no "
                       "velocity changes by more than decouple.tolerance, at most this many times"),
      CELLPHYS_SETTING(decouple_tolerance, "decouple.tolerance", at_least(0), "see decouple.sweeps (m/s)"),
      CELLPHYS_SETTING(region_min, "region.min", none(),
                       "simulated region: bodies whose bounding box leaves it are not collided (m)"),
      CELLPHYS_SETTING(region_max, "region.max", none(), "see region.min (m)"),
  };
}

#undef CELLPHYS_SETTING

std::vector<Setting> build_table() {
  std::vector<Setting> t = world_settings();
  for (int i = 0; i < gen::kNumGlobals; ++i) {
    const gen::GlobalInfo& g = gen::kGlobalTable[i];
    Bounds b;
    b.has_min = g.param.has_min;
    b.min_exclusive = g.param.min_exclusive;
    b.min = g.param.min;
    t.push_back({std::string("globals.") + g.param.name, g.setting,
                 g.param.lanes == 1 ? SettingType::f32 : SettingType::vec3,
                 offsetof(WorldSettings, globals) + g.field_offset, b, g.param.doc});
  }
  // A force's global placed where another setting is (a force named decouple with a global
  // decouple_sweeps, say) would make the scene format ambiguous.
  for (size_t i = 0; i < t.size(); ++i)
    for (size_t k = 0; k < i; ++k) {
      const std::string &a = t[i].path, &b = t[k].path;
      if (a == b || a.rfind(b + ".", 0) == 0 || b.rfind(a + ".", 0) == 0)
        throw std::logic_error("settings." + a + " (" + t[i].name + ") collides with settings." + b + " (" +
                               t[k].name + ")");
    }
  return t;
}

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

}  // namespace

const std::vector<Setting>& settings_table() {
  static const std::vector<Setting> table = build_table();
  return table;
}

const Setting* find_setting(const std::string& path) {
  for (const Setting& row : settings_table())
    if (row.path == path) return &row;
  return nullptr;
}

void* field_of(WorldSettings& s, const Setting& row) { return reinterpret_cast<unsigned char*>(&s) + row.offset; }
const void* field_of(const WorldSettings& s, const Setting& row) {
  return reinterpret_cast<const unsigned char*>(&s) + row.offset;
}

std::string value_problem(const Setting& row, double v) {
  switch (row.type) {
    case SettingType::integrator:
      return v >= 0 && v < spu::kNumIntegrators ? "" : "unknown integrator " + number(v);
    case SettingType::solver: return v >= 0 && v < spu::kNumSolvers ? "" : "unknown solver " + number(v);
    case SettingType::boolean: return "";
    case SettingType::f32:
    case SettingType::vec3:
      if (!std::isfinite(v)) return "must be finite";
      break;
    case SettingType::u32:
    case SettingType::i32:
    case SettingType::size: break;
  }
  const Bounds& b = row.bounds;
  const bool low = b.has_min && (b.min_exclusive ? !(v > b.min) : !(v >= b.min)), high = b.has_max && !(v <= b.max);
  if (!low && !high) return "";
  if (b.has_min && b.has_max && !b.min_exclusive) return "must be between " + number(b.min) + " and " + number(b.max);
  if (high) return "must be at most " + number(b.max);
  if (b.min_exclusive) return b.min == 0 ? "must be positive" : "must be > " + number(b.min);
  return "must be >= " + number(b.min);
}

void validate_settings(const WorldSettings& s) {
  for (const Setting& row : settings_table()) {
    const void* f = field_of(s, row);
    auto check = [&](double v, const std::string& where) {
      const std::string why = value_problem(row, v);
      if (!why.empty()) throw WorldError("settings." + where + ": " + why);
    };
    switch (row.type) {
      case SettingType::f32: check(*static_cast<const float*>(f), row.name); break;
      case SettingType::vec3:
        for (int k = 0; k < 3; ++k) check(static_cast<const float*>(f)[k], row.name + "[" + std::to_string(k) + "]");
        break;
      case SettingType::u32: check(*static_cast<const uint32_t*>(f), row.name); break;
      case SettingType::i32: check(*static_cast<const int*>(f), row.name); break;
      case SettingType::size: check(double(*static_cast<const size_t*>(f)), row.name); break;
      case SettingType::boolean: break;
      case SettingType::integrator: check(double(*static_cast<const spu::Integrator*>(f)), row.name); break;
      case SettingType::solver: check(double(*static_cast<const spu::Solver*>(f)), row.name); break;
    }
  }
}

}  // namespace cellphys::ppe

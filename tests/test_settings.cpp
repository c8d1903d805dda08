// The settings table (runtime/ppe/settings.h): every WorldSettings field has one row, each
// row's place in a scene file is unambiguous, and the World, the scene reader, the writer,
// equality and snapshots agree on every row: a value the World refuses the reader refuses at
// the row's path with the same reason, and a value it accepts survives writing, reading and a
// snapshot.
#include <gtest/gtest.h>

#include <cstring>
#include <string>

#include "runtime/ppe/settings.h"
#include "runtime/scene/scene.h"

namespace {

using namespace cellphys;
using ppe::Setting;
using ppe::SettingType;

// A value of `row` other than its default and within its bounds.
void set_other(ppe::WorldSettings& s, const Setting& row) {
  void* f = ppe::field_of(s, row);
  const ppe::Bounds& b = row.bounds;
  const double lo = b.has_min ? b.min : 0, hi = b.has_max ? b.max : lo + 100;
  switch (row.type) {
    case SettingType::f32: *static_cast<float*>(f) = float(lo + 0.75); break;
    case SettingType::vec3:
      for (int k = 0; k < 3; ++k) static_cast<float*>(f)[k] += 0.5f * float(k + 1);
      break;
    case SettingType::u32: {
      uint32_t& v = *static_cast<uint32_t*>(f);
      v = v == uint32_t(hi) ? uint32_t(lo) : uint32_t(hi);
      break;
    }
    case SettingType::i32: {
      int& v = *static_cast<int*>(f);
      v = v == int(hi) ? int(lo) : int(hi);
      break;
    }
    case SettingType::size: {
      size_t& v = *static_cast<size_t*>(f);
      v = v == size_t(lo) ? size_t(lo) * 2 : size_t(lo);
      break;
    }
    case SettingType::boolean: *static_cast<bool*>(f) = !*static_cast<bool*>(f); break;
    case SettingType::integrator: *static_cast<spu::Integrator*>(f) = spu::Integrator::rk4; break;
    case SettingType::solver: *static_cast<spu::Solver*>(f) = spu::Solver::direct; break;
  }
}

// A JSON scene with one setting of `row` at its place, the value given as JSON text.
std::string scene_with(const Setting& row, const std::string& value) {
  std::string open, close;
  std::string rest = row.path;
  for (size_t dot; (dot = rest.find('.')) != std::string::npos; rest = rest.substr(dot + 1)) {
    open += "\"" + rest.substr(0, dot) + "\": {";
    close += "}";
  }
  return "{\"settings\": {" + open + "\"" + rest + "\": " + value + close + "}}";
}

TEST(Settings, EveryRowHasItsOwnPlaceAndTheDefaultsAreValid) {
  const auto& table = ppe::settings_table();  // throws when two places collide
  ASSERT_FALSE(table.empty());
  for (const Setting& row : table) {
    SCOPED_TRACE(row.name);
    EXPECT_EQ(ppe::find_setting(row.path), &row);
    EXPECT_FALSE(row.doc.empty());
  }
  EXPECT_NO_THROW(ppe::validate_settings(ppe::WorldSettings{}));
  int globals = 0;
  for (const Setting& row : table) globals += row.name.rfind("globals.", 0) == 0;
  EXPECT_EQ(globals, gen::kNumGlobals) << "every force global is a row";
}

TEST(Settings, EveryRowSurvivesWritingReadingAndASnapshot) {
  for (const Setting& row : ppe::settings_table()) {
    SCOPED_TRACE(row.name);
    scene::SceneDesc d;
    set_other(d.settings, row);
    ASSERT_NO_THROW(ppe::validate_settings(d.settings));
    EXPECT_FALSE(scene::operator==(d.settings, ppe::WorldSettings{}));
    const scene::SceneDesc again = scene::parse_scene(scene::write_scene(d), "written.json");
    EXPECT_TRUE(scene::operator==(again.settings, d.settings));
    const ppe::World w(d.settings);
    const std::vector<unsigned char> bytes = w.snapshot();
    EXPECT_TRUE(scene::operator==(ppe::World::restore(bytes.data(), bytes.size())->settings(), d.settings));
  }
}

TEST(Settings, TheWorldAndTheReaderRefuseTheSameValuesForTheSameReason) {
  int bounded = 0;
  for (const Setting& row : ppe::settings_table()) {
    const ppe::Bounds& b = row.bounds;
    if (!b.has_min && !b.has_max) continue;
    SCOPED_TRACE(row.name);
    ++bounded;
    const bool whole = row.type == SettingType::u32 || row.type == SettingType::i32 || row.type == SettingType::size;
    const double bad = b.has_max ? b.max + 1 : b.min_exclusive ? b.min : b.min - (whole ? 1 : 0.5);
    if (whole && bad < 0) continue;  // not representable; the type itself refuses it
    ppe::WorldSettings s;
    void* f = ppe::field_of(s, row);
    switch (row.type) {
      case SettingType::f32: *static_cast<float*>(f) = float(bad); break;
      case SettingType::vec3: static_cast<float*>(f)[0] = float(bad); break;
      case SettingType::u32: *static_cast<uint32_t*>(f) = uint32_t(bad); break;
      case SettingType::i32: *static_cast<int*>(f) = int(bad); break;
      case SettingType::size: *static_cast<size_t*>(f) = size_t(bad); break;
      default: FAIL() << "bounds on a setting that is not a number";
    }
    const std::string reason = ppe::value_problem(row, bad);
    ASSERT_FALSE(reason.empty());
    try {
      ppe::World w(s);
      ADD_FAILURE() << "the World accepted " << bad;
    } catch (const ppe::WorldError& e) {
      const std::string where = "settings." + row.name + (row.type == SettingType::vec3 ? "[0]" : "");
      EXPECT_EQ(std::string(e.what()), where + ": " + reason);
    }
    char text[64];
    std::snprintf(text, sizeof text, whole ? "%.0f" : "%.9g", bad);
    const std::string value = row.type == SettingType::vec3 ? std::string("[") + text + ", 0, 0]" : text;
    try {
      scene::parse_scene(scene_with(row, value), "bad.json");
      ADD_FAILURE() << "the reader accepted " << value;
    } catch (const scene::SceneError& e) {
      EXPECT_EQ(e.path(), "settings." + row.path + (row.type == SettingType::vec3 ? "[0]" : ""));
      EXPECT_EQ(e.reason(), reason);
    }
  }
  EXPECT_GE(bounded, 10);
}

TEST(Settings, NamesOfIntegratorsAndSolversComeFromTheirTables) {
  for (int k = 0; k < spu::kNumIntegrators; ++k) {
    spu::Integrator i{};
    ASSERT_TRUE(spu::parse_integrator(spu::integrator_name(spu::Integrator(k)), &i));
    EXPECT_EQ(i, spu::Integrator(k));
    EXPECT_NE(spu::integrator_names().find(spu::integrator_name(i)), std::string::npos);
  }
  for (int k = 0; k < spu::kNumSolvers; ++k) {
    spu::Solver v{};
    ASSERT_TRUE(spu::parse_solver(spu::solver_name(spu::Solver(k)), &v));
    EXPECT_EQ(v, spu::Solver(k));
    EXPECT_NE(spu::solver_names().find(spu::solver_name(v)), std::string::npos);
  }
  spu::Solver v{};
  EXPECT_FALSE(spu::parse_solver("gmres", &v));
  try {
    scene::parse_scene(R"({"settings": {"solver": "gmres"}})", "s.json");
    ADD_FAILURE() << "accepted";
  } catch (const scene::SceneError& e) {
    EXPECT_NE(e.reason().find("(known: " + spu::solver_names() + ")"), std::string::npos) << e.what();
  }
}

}  // namespace

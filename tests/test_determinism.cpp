// The same bits on every SIMD path, thread count and machine (docs/determinism.md): each
// built-in scene, and the code paths its defaults do not reach, ends on a state hash pinned
// here. The constants are the same on every build; the release, avx2 and scalar test passes
// each assert them, so a change that makes one path round differently fails on that path.
#include <gtest/gtest.h>

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <string>

#include "runtime/base/trig.h"
#include "runtime/ppe/world.h"
#include "runtime/scene/scene.h"

namespace {

using cellphys::ppe::World;
using cellphys::ppe::WorldSettings;

std::string scene_file(const std::string& name) {
  return std::string(CELLPHYS_SCENES_DIR) + "/" + name + ".json";
}

struct Pinned {
  const char* scene;
  int steps;
  const char* variant;                         // what the tweak changes, for the message
  std::function<void(WorldSettings&)> tweak;   // nullptr: the scene's own settings
  uint64_t hash;
};

std::string hex(uint64_t h) {
  char s[17];
  std::snprintf(s, sizeof s, "%016" PRIx64, h);
  return s;
}

uint64_t run(const Pinned& p, int workers) {
  auto built = cellphys::scene::build_world(cellphys::scene::load_scene(scene_file(p.scene)));
  World& w = *built.world;
  WorldSettings s = w.settings();
  if (p.tweak) p.tweak(s);
  s.workers = workers;
  w.set_settings(s);
  for (int i = 0; i < p.steps; ++i) w.step();
  return w.state_hash();
}

const Pinned kPinned[] = {
    {"world1000", 60, "defaults", nullptr, 0x85a131095a4a127aull},
    {"pile65", 45, "defaults", nullptr, 0x92c07b59cfab0ba7ull},
    {"stack10", 60, "defaults", nullptr, 0x931503ba140b55c6ull},
    {"chain_ratio", 60, "defaults", nullptr, 0xc1842c74daadf229ull},
    {"incline", 60, "defaults", nullptr, 0x21cb5466c086f3dbull},
    {"newton_cradle", 60, "defaults", nullptr, 0x7a7540d9e86d016bull},
    {"pendulum", 60, "defaults", nullptr, 0xc51bbcf744cd70faull},
    {"spin", 60, "defaults", nullptr, 0xb07ba66c3976cc56ull},
    {"stiff_spring", 60, "defaults", nullptr, 0x454496659ef4e821ull},
    // Paths the defaults leave out: a pile decoupled into local-store parts, the other
    // integrators and solvers.
    {"pile65", 45, "decoupled in a 64 KiB local store",
     [](WorldSettings& s) { s.local_store_bytes = 64 * 1024, s.whole_island_bytes = 0; }, 0x75546c2c61636fcdull},
    {"pile65", 30, "rosenbrock, bicgstab",
     [](WorldSettings& s) {
       s.integrator = cellphys::spu::Integrator::rosenbrock;
       s.solver = cellphys::spu::Solver::bicgstab;
     },
     0x468b13b18d802776ull},
    {"chain_ratio", 30, "implicit_euler, direct",
     [](WorldSettings& s) {
       s.integrator = cellphys::spu::Integrator::implicit_euler;
       s.solver = cellphys::spu::Solver::direct;
     },
     0x21485e45796dff6cull},
    {"spin", 60, "rk4", [](WorldSettings& s) { s.integrator = cellphys::spu::Integrator::rk4; }, 0x9a13b5724e8a615bull},
};

void PrintTo(const Pinned& p, std::ostream* os) { *os << p.scene << " (" << p.variant << ")"; }

class PinnedHash : public ::testing::TestWithParam<Pinned> {};

TEST_P(PinnedHash, IsTheSameOnEveryPathAndThreadCount) {
  const Pinned& p = GetParam();
  const uint64_t one = run(p, 1);
  EXPECT_EQ(hex(one), hex(p.hash)) << p.scene << " (" << p.variant << ") after " << p.steps
                                   << " steps on the " << CELLPHYS_SIMD_PATH_NAME << " path";
  EXPECT_EQ(hex(run(p, 3)), hex(one)) << "three workers must give the one-worker bits";
}

std::string name_of(const ::testing::TestParamInfo<Pinned>& info) {
  std::string n = std::string(info.param.scene) + "_" + std::to_string(info.index);
  return n;
}

INSTANTIATE_TEST_SUITE_P(BuiltInScenes, PinnedHash, ::testing::ValuesIn(kPinned), name_of);

double ulp(double v) { return std::nextafter(std::fabs(v), INFINITY) - std::fabs(v); }

// The project's sine and cosine (runtime/base/trig.h): close to the C library's, and
// reproducible bit for bit (a digest of many values pinned).
TEST(Trig, WithinTwoUlpOfTheLibraryAndOddEven) {
  uint64_t state = 0x9E3779B97F4A7C15ull;
  for (int i = 0; i < 200000; ++i) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    const double u = double(state >> 11) / 9007199254740992.0;  // [0, 1)
    const double x = (i % 3 == 0 ? 1e-6 : i % 3 == 1 ? 4.0 : 2000.0) * (2 * u - 1);
    double s, c;
    cellphys::sin_cos(x, &s, &c);
    ASSERT_NEAR(s, std::sin(x), 2 * ulp(std::sin(x))) << "sin " << x;
    ASSERT_NEAR(c, std::cos(x), 2 * ulp(std::cos(x))) << "cos " << x;
    double s2, c2;
    cellphys::sin_cos(-x, &s2, &c2);
    ASSERT_EQ(s2, -s) << x;
    ASSERT_EQ(c2, c) << x;
  }
}

TEST(Trig, DigestIsPinned) {
  uint64_t digest = 1469598103934665603ull;  // FNV-1a over the bits of sin and cos
  for (int i = -20000; i <= 20000; ++i) {
    double s, c;
    cellphys::sin_cos(i * 0.00731, &s, &c);
    for (double v : {s, c}) {
      uint64_t b;
      std::memcpy(&b, &v, 8);
      for (int k = 0; k < 8; ++k) digest = (digest ^ ((b >> (8 * k)) & 0xFF)) * 1099511628211ull;
    }
  }
  EXPECT_EQ(hex(digest), hex(0x0186f9da4bf43b16ull));
}

}  // namespace

// One-body islands that touch only the world share an image on the world's own threads
// (runtime/ppe/step_integrate.cpp): each must get the bits it gets packed alone, as a runner
// that is handed every island in an image of its own (compute nodes, say) gives it.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "runtime/ppe/island_runner.h"
#include "runtime/ppe/world.h"
#include "runtime/spu/kernel.h"
#include "testing/scenes.h"

namespace {

using namespace cellphys;
using namespace cellphys::testing;
using ppe::StepStats;
using ppe::World;
using ppe::WorldSettings;

// Steps every image it is handed, one after another, each in an image of its own: the world
// packs islands one to an image for any runner but its own worker pool.
class OneByOne : public ppe::IslandRunner {
 public:
  void set_local_store(size_t bytes) override { bytes_ = bytes; }
  void run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) override {
    spu::ComputeWorker worker(bytes_);
    reports.clear();
    for (const spu::IslandJob& j : jobs) reports.push_back(worker.step(j));
  }
  const char* name() const override { return "one by one"; }

 private:
  size_t bytes_ = spu::LocalStore::kDefaultCapacity;
};

// Lone bodies of every kind the runtime packs: sparse_world's boxes, balls, capsules and hulls
// resting, sliding and dropped (and its stacked pairs, which are not lone); bricks in the air
// spun so fast that their first step fails in the rotation and halves; boxes swinging on
// hinges to the world; damped balls falling; boxes at rest on the ground whose forces all but
// cancel (their solve stops at the absolute tolerance: a solve of several bodies together would
// not).
std::vector<BodyId> lone_bodies(World& w, uint32_t seed) {
  std::vector<BodyId> ids = sparse_world(w, 240, 50.0f, seed);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  for (int k = 0; k < 12; ++k) {
    const float half[3] = {0.4f + U(rng), 0.1f, 0.2f}, pos[3] = {60.0f + 16.0f * float(k), 0.0f, 20.0f};
    ppe::BodyDesc d;
    d.shape = w.shapes().add_box(half);
    d.mass = 0.5f + 4.0f * U(rng);
    std::copy(pos, pos + 3, d.state.position);
    for (float& x : d.state.angular_velocity) x = 300.0f * (2.0f * U(rng) - 1.0f);
    ids.push_back(w.add_body(d));
  }
  for (int k = 0; k < 6; ++k) {
    const float half[3] = {0.5f, 0.05f, 0.05f}, pos[3] = {-60.0f - 3.0f * float(k), 0.0f, 5.0f + 0.5f * float(k)};
    const BodyId bar = add_box(w, half, 0.5f + U(rng), pos);
    w.add_force("hinge", bar, ppe::kWorldBody,
                {{"point_a", {-0.5f, 0, 0}}, {"point_b", {pos[0] - 0.5f, pos[1], pos[2] + 0.3f}},
                 {"axis_a", {0, 1, 0}}, {"axis_b", {0, 1, 0}}, {"ref_a", {1, 0, 0}}, {"ref_b", {1, 0, 0}}});
    ids.push_back(bar);
  }
  for (int k = 0; k < 8; ++k) {
    ppe::BodyDesc d;
    d.shape = w.shapes().add_sphere(0.2f + 0.3f * U(rng));
    d.mass = 0.2f + 20.0f * U(rng);
    d.linear_damping = 0.5f * U(rng);
    d.angular_damping = 0.5f * U(rng);
    d.state.position[0] = -30.0f + 8.0f * float(k);
    d.state.position[1] = 40.0f;
    d.state.position[2] = 3.0f + float(k);
    ids.push_back(w.add_body(d));
  }
  for (int k = 0; k < 10; ++k) {
    const float half[3] = {0.25f, 0.25f, 0.25f}, pos[3] = {-30.0f + 6.0f * float(k), -40.0f, 0.25f};
    ids.push_back(add_box(w, half, 0.1f + 10.0f * float(k), pos));
  }
  return ids;
}

// The world's own pool (images shared) against islands one to an image, step after step.
void expect_same_bits(int workers, uint32_t seed) {
  WorldSettings s;
  s.sleeping = false;
  s.workers = workers;
  World shared(s), alone(s);
  lone_bodies(shared, seed);
  lone_bodies(alone, seed);
  alone.set_runner(std::make_shared<OneByOne>());
  uint32_t shared_islands = 0, halved_steps = 0;
  for (int step = 0; step < 40; ++step) {
    const StepStats a = shared.step(), b = alone.step();
    ASSERT_EQ(b.shared_islands, 0u) << "a runner of its own is handed one island to an image";
    EXPECT_GT(a.shared_islands, 100u) << "step " << step << ": lone islands were not packed together";
    EXPECT_LT(a.shared_islands, a.islands) << "step " << step << ": the stacked pairs are not lone";
    shared_islands += a.shared_islands;
    halved_steps += a.step_halvings > 0;
    EXPECT_EQ(a.failed_islands, b.failed_islands) << "step " << step;
    EXPECT_EQ(a.step_halvings, b.step_halvings) << "step " << step;
    EXPECT_EQ(a.solves, b.solves) << "step " << step;
    EXPECT_EQ(a.solver_iterations, b.solver_iterations) << "step " << step;
    EXPECT_EQ(a.substeps, b.substeps) << "step " << step;
    ASSERT_EQ(shared.state_hash(), alone.state_hash()) << "step " << step << ", " << workers << " worker(s)";
  }
  EXPECT_GE(halved_steps, 1u) << "the spinning bricks' first step must halve in a shared image";
}

TEST(SharedImages, LoneIslandsGetTheBitsEachGetsInAnImageOfItsOwn) {
  expect_same_bits(1, 5);
  expect_same_bits(2, 6);
}

TEST(SharedImages, NotForTheAdaptiveStep) {
  // ROS2's error estimate, and so its step sizes, would be the whole image's
  WorldSettings s;
  s.sleeping = false;
  s.integrator = spu::Integrator::rosenbrock;
  World w(s);
  sparse_world(w, 100, 30.0f, 2);
  for (int step = 0; step < 3; ++step) {
    const StepStats st = w.step();
    EXPECT_GT(st.islands, 50u);
    EXPECT_EQ(st.shared_islands, 0u) << "step " << step;
  }
  s.integrator = spu::Integrator::implicit_split;  // the same world, the default step: shared
  World v(s);
  sparse_world(v, 100, 30.0f, 2);
  EXPECT_GT(v.step().shared_islands, 50u);
}

}  // namespace

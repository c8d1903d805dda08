// What a step visits is kept as bodies change, not found by a pass over every body: the tree of
// the still bodies' boxes against brute force, the pairs set aside while their bodies sleep,
// and a world kept incrementally against the same world filed afresh every step (bit for bit,
// through sleeping, waking, bodies added and removed, a static body moved, a sensor, and bodies
// outside the region).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "runtime/ppe/box_tree.h"
#include "runtime/ppe/broad_phase.h"
#include "runtime/ppe/dormant_pairs.h"
#include "runtime/ppe/world.h"
#include "testing/scenes.h"

namespace {

using namespace cellphys;
using namespace cellphys::testing;
using ppe::Aabb;
using ppe::BoxTree;
using ppe::DormantPairs;

Aabb random_box(std::mt19937& rng, float world, float largest) {
  std::uniform_real_distribution<float> at(-world, world), size(0.0f, largest);
  Aabb b;
  for (int k = 0; k < 3; ++k) {
    b.min[k] = at(rng);
    b.max[k] = b.min[k] + size(rng);
  }
  return b;
}

TEST(BoxTree, FindsWhatBruteForceFindsThroughInsertsAndRemovesAndStaysBalanced) {
  std::mt19937 rng(7);
  BoxTree tree;
  std::vector<Aabb> boxes;
  std::vector<int32_t> leaf;
  std::vector<uint32_t> live;
  for (int round = 0; round < 4000; ++round) {
    const bool add = live.size() < 50 || rng() % 3 != 0;
    if (add) {
      const uint32_t id = static_cast<uint32_t>(boxes.size());
      boxes.push_back(random_box(rng, 50.0f, round % 97 == 0 ? 60.0f : 3.0f));  // now and then a huge box
      leaf.push_back(tree.insert(id, boxes.back()));
      live.push_back(id);
    } else {
      const size_t k = rng() % live.size();
      tree.remove(leaf[live[k]]);
      live.erase(live.begin() + k);
    }
    if (round % 200 != 199) continue;
    ASSERT_EQ(tree.size(), live.size());
    // An AVL tree of n leaves is at most about 1.44 log2(n) high.
    EXPECT_LE(tree.height(), int(1.45 * std::log2(double(live.size())) + 2)) << live.size() << " leaves";
    for (int q = 0; q < 50; ++q) {
      const Aabb query = random_box(rng, 50.0f, 8.0f);
      std::vector<uint32_t> found, expected;
      tree.overlap(query, [&](uint32_t id) { found.push_back(id); });
      for (uint32_t id : live)
        if (ppe::boxes_meet(boxes[id], query)) expected.push_back(id);
      std::sort(found.begin(), found.end());
      std::sort(expected.begin(), expected.end());
      ASSERT_EQ(found, expected);
    }
  }
}

TEST(BoxTree, BoxesThatOnlyTouchMeet) {
  BoxTree tree;
  tree.insert(3, Aabb{{0, 0, 0}, {1, 1, 1}});
  int found = 0;
  tree.overlap(Aabb{{1, 1, 1}, {2, 2, 2}}, [&](uint32_t id) { found += id == 3; });
  EXPECT_EQ(found, 1);
  tree.overlap(Aabb{{1.0001f, 0, 0}, {2, 1, 1}}, [&](uint32_t) { ++found; });
  EXPECT_EQ(found, 1);
}

// The sweep tests its candidates a block at a time: it must find what brute force finds,
// whatever the count (blocks ending anywhere), the spread (bands of hundreds of candidates,
// as in a pile), boxes that only touch, and with boxes that are not awake among them; and it
// must keep finding them as the boxes move on and the order is mended from the last step's.
TEST(SweepAndPrune, FindsWhatBruteForceFindsInDenseAndSparseBandsAsBoxesMove) {
  std::mt19937 rng(11);
  for (int count : {0, 1, 2, 15, 16, 17, 33, 300, 1200}) {
    for (float world : {2.0f, 40.0f}) {
      std::vector<Aabb> boxes;
      std::vector<ppe::BoxKind> kind;
      std::vector<uint32_t> ids;
      for (int i = 0; i < count; ++i) {
        boxes.push_back(random_box(rng, world, 3.0f));
        kind.push_back(rng() % 7 == 0 ? ppe::BoxKind::asleep : ppe::BoxKind::awake);
        ids.push_back(uint32_t(i));
      }
      if (count >= 2) {  // two boxes that only touch (along x, y or z by the count)
        boxes[1] = boxes[0];
        boxes[1].min[count % 3] = boxes[0].max[count % 3];
        boxes[1].max[count % 3] = boxes[0].max[count % 3] + 1.0f;
        kind[0] = kind[1] = ppe::BoxKind::awake;
      }
      ppe::SweepAndPrune sap;
      for (int step = 0; step < 3; ++step) {
        std::vector<std::pair<uint32_t, uint32_t>> found, expected;
        sap.find_pairs(boxes, kind, ids, found);
        for (int i = 0; i < count; ++i)
          for (int j = i + 1; j < count; ++j)
            if (kind[i] == ppe::BoxKind::awake && kind[j] == ppe::BoxKind::awake && ppe::boxes_meet(boxes[i], boxes[j]))
              expected.emplace_back(i, j);
        std::sort(found.begin(), found.end());
        ASSERT_EQ(found, expected) << count << " boxes in " << world << " m, step " << step;
        if (count >= 2 && step == 0) {
          EXPECT_TRUE(std::binary_search(found.begin(), found.end(), std::make_pair(0u, 1u)));
        }
        std::normal_distribution<float> move(0.0f, 0.2f * world);  // far enough to reorder
        for (Aabb& b : boxes)
          for (int k = 0; k < 3; ++k) {
            const float d = move(rng);
            b.min[k] += d, b.max[k] += d;
          }
      }
    }
  }
}

// A box that reaches to +inf (a body flung to infinity, as a damaged snapshot can hold) is in
// every later box's band: the sweep stops at the last box, not in the padding after it.
TEST(SweepAndPrune, ABoxReachingInfinityMeetsTheBoxesAfterItAndNothingPastTheLast) {
  std::mt19937 rng(5);
  const float inf = std::numeric_limits<float>::infinity();
  for (int count : {1, 2, 5, 16, 17, 40}) {
    std::vector<Aabb> boxes;
    std::vector<ppe::BoxKind> kind(size_t(count), ppe::BoxKind::awake);
    std::vector<uint32_t> ids;
    for (int i = 0; i < count; ++i) {
      boxes.push_back(random_box(rng, 4.0f, 1.0f));
      if (i % 3 == 0)
        for (int k = 0; k < 3; ++k) boxes.back().max[k] = inf;
      ids.push_back(uint32_t(i));
    }
    ppe::SweepAndPrune sap;
    std::vector<std::pair<uint32_t, uint32_t>> found, expected;
    sap.find_pairs(boxes, kind, ids, found);
    for (int i = 0; i < count; ++i)
      for (int j = i + 1; j < count; ++j)
        if (ppe::boxes_meet(boxes[i], boxes[j])) expected.emplace_back(i, j);
    std::sort(found.begin(), found.end());
    EXPECT_EQ(found, expected) << count << " boxes";
  }
}

TEST(DormantPairs, AWokenBodyTakesBackEveryPairOfItsOnceAndNoOther) {
  DormantPairs d;
  auto key = [](uint32_t a, uint32_t b) { return uint64_t(a) << 32 | b; };
  std::vector<uint64_t> keys = {key(5, 9), key(1, 5), key(2, 3), key(5, UINT32_MAX), key(7, 9)};
  d.add(keys);
  std::vector<uint64_t> out;
  d.take({5, 9}, out);  // (5, 9) has both: once
  std::sort(out.begin(), out.end());
  EXPECT_EQ(out, (std::vector<uint64_t>{key(1, 5), key(5, 9), key(5, UINT32_MAX), key(7, 9)}));
  EXPECT_EQ(d.keys(), (std::vector<uint64_t>{key(2, 3)}));
  out.clear();
  d.take({4, UINT32_MAX}, out);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(d.keys().size(), 1u);
}

// Two copies of one world; the second files every body afresh each step (changed settings do).
class Twins {
 public:
  Twins() {
    for (World* w : {&kept_, &fresh_}) {
      ppe::WorldSettings s = w->settings();
      s.region_min[0] = -12.0f;  // the bodies beyond x = -12 are outside and left alone
      w->set_settings(s);
      ids_ = sparse_world(*w, 300, 30.0f, 5);
      const float half[3] = {1.5f, 1.5f, 0.5f}, at[3] = {4.0f, 4.0f, 0.5f};
      ppe::BodyDesc d;
      d.shape = w->shapes().add_box(half);
      d.is_static = true;
      d.state.position[0] = at[0], d.state.position[1] = at[1], d.state.position[2] = at[2];
      wall_ = w->add_body(d);
      d.sensor = true;
      d.state.position[0] = -4.0f;
      w->add_body(d);
    }
  }
  template <class F>
  void both(F f) { f(kept_), f(fresh_); }
  void step_and_compare(int step) {
    fresh_.set_settings(fresh_.settings());
    const ppe::StepStats a = kept_.step(), b = fresh_.step();
    ASSERT_EQ(kept_.state_hash(), fresh_.state_hash()) << "step " << step;
    ASSERT_EQ(a.active_bodies, b.active_bodies) << "step " << step;
    ASSERT_EQ(a.sleeping_bodies, b.sleeping_bodies) << "step " << step;
    ASSERT_EQ(a.broad_phase_boxes, b.broad_phase_boxes) << "step " << step;
    ASSERT_EQ(a.outside_region, b.outside_region) << "step " << step;
    ASSERT_EQ(a.mid_phase_pairs, b.mid_phase_pairs) << "step " << step;
    ASSERT_EQ(kept_.contact_events().size(), fresh_.contact_events().size()) << "step " << step;
    ASSERT_EQ(kept_.sensor_events().size(), fresh_.sensor_events().size()) << "step " << step;
    most_asleep_ = std::max(most_asleep_, a.sleeping_bodies);
    woken_ += a.woken;
    outside_ = std::max(outside_, a.outside_region);
  }
  const std::vector<BodyId>& ids() const { return ids_; }
  BodyId wall() const { return wall_; }
  uint32_t most_asleep_ = 0, woken_ = 0, outside_ = 0;

 private:
  World kept_, fresh_;
  std::vector<BodyId> ids_;
  BodyId wall_ = 0;
};

TEST(AwakeSets, AWorldKeptAsItChangesStepsBitForBitLikeOneFiledAfreshEachStep) {
  Twins t;
  std::mt19937 rng(11);
  for (int step = 1; step <= 420; ++step) {
    if (step % 23 == 0) {  // a kick wakes a sleeper, a ball dropped on another wakes it in the step
      const BodyId b = t.ids()[rng() % t.ids().size()], c = t.ids()[rng() % t.ids().size()];
      const float impulse[3] = {0.5f, 0.0f, 3.0f};
      t.both([&](World& w) {
        if (w.has_body(b)) w.apply_impulse(b, impulse, w.state(b).position);  // (the state outlives the call)
        if (!w.has_body(c)) return;
        const ppe::BodyState at = w.state(c);
        const float above[3] = {at.position[0], at.position[1], at.position[2] + 1.2f};
        add_sphere(w, 0.2f, 3.0f, above);
      });
    }
    if (step == 200) t.both([&](World& w) { w.remove_body(t.ids()[17]); });
    const float drop[3] = {4.0f, 4.0f, 3.0f};  // onto the wall
    if (step == 210) t.both([&](World& w) { add_sphere(w, 0.3f, 2.0f, drop); });
    if (step == 260) t.both([&](World& w) {  // the static wall moves under what rests on it
      ppe::BodyState s = w.state(t.wall());
      s.position[2] = 0.45f;
      w.set_state(t.wall(), s);
    });
    t.step_and_compare(step);
    if (::testing::Test::HasFatalFailure()) return;
  }
  // The run slept and woke, and had bodies outside the region, so each path was taken.
  EXPECT_GT(t.most_asleep_, 100u);
  EXPECT_GT(t.woken_, 5u);
  EXPECT_GT(t.outside_, 0u);
}

}  // namespace

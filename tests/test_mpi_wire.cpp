// The compute-node messages without MPI: a loopback runner ships every island through the
// wire codec (runtime/ppe/wire.h) to a node kernel in this process, so the world's results
// must equal the worker pool's bit for bit, and damage on the way must be caught and the
// island recomputed.
#include <gtest/gtest.h>

#include <cstring>

#include "runtime/ppe/island_runner.h"
#include "runtime/ppe/wire.h"
#include "runtime/ppe/world.h"
#include "runtime/scene/scene.h"

namespace {

using namespace cellphys;
using ppe::World;

class LoopbackRunner : public ppe::IslandRunner {
 public:
  int corrupt_at = -1;  // damage reply number N
  uint64_t replies = 0;
  void set_local_store(size_t bytes) override { ls_ = bytes; }
  void run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) override {
    last_ = {};
    reports.assign(jobs.size(), {});
    ++seq_;
    for (uint32_t k = 0; k < jobs.size(); ++k) {
      ppe::wire::encode_job(jobs[k].image, jobs[k].bytes, seq_, k, ls_, out_);
      EXPECT_EQ(out_.size(), ppe::wire::job_bytes(jobs[k].bytes, view_bodies(jobs[k])));
      last_.bytes_to_nodes += out_.size();
      node_.serve(out_.data(), out_.size(), back_);
      if (static_cast<int64_t>(replies++) == corrupt_at) back_[back_.size() / 2] ^= 0x01;
      last_.bytes_from_nodes += back_.size();
      const std::string why = ppe::wire::decode_result(back_.data(), back_.size(), seq_, k, jobs[k].image, jobs[k].result,
                                                       jobs[k].result_capacity, reports[k]);
      if (!why.empty()) {
        ++last_.bad_messages;
        std::memset(jobs[k].result, 0, sizeof(gen::Island_Result));
        reports[k].status = spu::IslandStatus::malformed;
      }
    }
  }
  ppe::TransportCounters last_transport() const override { return last_; }
  const char* name() const override { return "loopback"; }

 private:
  static size_t view_bodies(const spu::IslandJob& j) {
    gen::Island_Header h;
    std::memcpy(&h, j.image, sizeof h);
    return h.num_bodies;
  }
  size_t ls_ = 0;
  uint32_t seq_ = 0;
  ppe::wire::NodeKernel node_;
  std::vector<unsigned char> out_, back_;
  ppe::TransportCounters last_;
};

std::unique_ptr<World> scene(const char* name) {
  auto built = scene::build_world(scene::load_scene(std::string(CELLPHYS_SCENES_DIR) + "/" + name + ".json"));
  return std::move(built.world);
}

struct Totals {
  uint64_t bodies = 0, to = 0, from = 0, table_out = 0, table_out_geometry = 0, table_back = 0, shared = 0;
  uint32_t recomputed = 0, bad = 0, islands = 0;
};

void same_as_pool(const char* name, int steps, int corrupt_at, Totals& t) {
  auto a = scene(name), b = scene(name);
  auto loop = std::make_shared<LoopbackRunner>();
  loop->corrupt_at = corrupt_at;
  b->set_runner(loop);
  for (int s = 0; s < steps; ++s) {
    a->step();
    const ppe::StepStats& st = b->step();
    ASSERT_EQ(a->state_hash(), b->state_hash()) << name << " diverged at step " << s + 1;
    t.bodies += st.island_bodies;
    t.to += st.bytes_to_nodes;
    t.from += st.bytes_from_nodes;
    t.table_out += st.wire_table_to_nodes_compressed;
    t.table_out_geometry += st.wire_table_to_nodes;
    t.table_back += st.wire_table_from_nodes;
    t.shared += st.island_bytes_shared;
    t.recomputed += st.recomputed_islands;
    t.bad += st.bad_messages;
    t.islands += st.islands + st.decoupled_islands;
  }
  EXPECT_EQ(a->last_stats().bytes_to_nodes, 0u) << "the worker pool moves no message bytes";
}

TEST(MpiWire, LoopbackEqualsWorkerPoolBitForBit) {
  for (const char* name : {"pile65", "world1000"}) {
    Totals t;
    same_as_pool(name, 45, -1, t);
    ASSERT_GT(t.bodies, 0u);
    EXPECT_EQ(t.recomputed, 0u);
    // out: the compressed table plus each island's shared records and a 40-byte header
    EXPECT_GE(t.to, t.table_out);
    EXPECT_EQ((t.to - t.table_out) % sizeof(ppe::wire::JobHeader), 0u);
    // back: exactly 13 floats per body plus one 80-byte header per island
    EXPECT_EQ(t.table_back, 52u * t.bodies);
    EXPECT_EQ((t.from - t.table_back) % sizeof(ppe::wire::ResultHeader), 0u);
  }
}

TEST(MpiWire, CompressedBodiesAreSmallerThanGeometryWhereShapesAreHulls) {
  Totals t;
  same_as_pool("world1000", 5, -1, t);
  EXPECT_LT(t.table_out, t.table_out_geometry) << "world1000 has hulls: a reference beats sending them";
}

TEST(MpiWire, DamagedReplyIsCaughtAndRecomputed) {
  Totals t;
  same_as_pool("world1000", 10, 100, t);  // hashes compared every step inside
  EXPECT_EQ(t.bad, 1u);
  EXPECT_EQ(t.recomputed, 1u);
}

TEST(MpiWire, DamagedJobIsRefusedByTheNode) {
  // a one-body island
  spu::IslandBuilder ib;
  gen::Rigid_Body_Fields f;
  f.mass = 1.0f;
  f.inverse_mass = 1.0f;
  for (int k = 0; k < 3; ++k) f.inertia_body[k] = 0.1f, f.inverse_inertia_body[k] = 10.0f;
  ib.add_body(f);
  const std::vector<unsigned char> image = ib.finish();
  std::vector<unsigned char> msg, back;
  ppe::wire::encode_job(image.data(), image.size(), 1, 0, 256 * 1024, msg);
  msg[msg.size() - 5] ^= 0x80;
  ppe::wire::NodeKernel node;
  node.serve(msg.data(), msg.size(), back);
  std::vector<unsigned char> result(spu::result_bytes(1));
  spu::IslandReport r;
  const std::string why = ppe::wire::decode_result(back.data(), back.size(), 1, 0, image.data(), result.data(), result.size(), r);
  EXPECT_FALSE(why.empty() && r.status == spu::IslandStatus::ok) << "a damaged job must not come back as a sound result";
  EXPECT_EQ(node.islands(), 0u);
}

}  // namespace

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

// One compute node: every wave is one jobs batch and one results batch.
class LoopbackRunner : public ppe::IslandRunner {
 public:
  int corrupt_at = -1;  // damage island result number N
  uint64_t replies = 0;
  uint32_t batches = 0;
  void set_local_store(size_t bytes) override { ls_ = bytes; }
  void run(const std::vector<spu::IslandJob>& jobs, std::vector<spu::IslandReport>& reports) override {
    last_ = {};
    reports.assign(jobs.size(), {});
    ++seq_;
    ppe::wire::begin_batch(ppe::wire::kJobsMagic, seq_, ls_, out_);
    size_t expected = sizeof(ppe::wire::BatchHeader);
    for (uint32_t k = 0; k < jobs.size(); ++k) {
      ppe::wire::append_job(jobs[k].image, jobs[k].bytes, k, out_);
      expected += ppe::wire::job_record_bytes(jobs[k].bytes, view_bodies(jobs[k]));
    }
    ppe::wire::seal_batch(out_);
    EXPECT_EQ(out_.size(), expected);
    last_.bytes_to_nodes += out_.size();
    ++last_.messages_to_nodes;
    ++batches;
    node_.serve(out_.data(), out_.size(), back_);
    const std::vector<size_t>& at = node_.record_offsets();
    EXPECT_EQ(at.size(), jobs.size());
    for (size_t i = 0; i < at.size(); ++i, ++replies)
      if (static_cast<int64_t>(replies) == corrupt_at) {
        const size_t end = i + 1 < at.size() ? at[i + 1] : back_.size();
        back_[(at[i] + end) / 2] ^= 0x01;
      }
    last_.bytes_from_nodes += back_.size();
    ++last_.messages_from_nodes;
    ppe::wire::BatchHeader h;
    ASSERT_EQ(ppe::wire::decode_batch_header(back_.data(), back_.size(), ppe::wire::kResultsMagic, h), "");
    ASSERT_EQ(h.sequence, seq_);
    ASSERT_EQ(h.count, jobs.size());
    size_t offset = sizeof h;
    std::vector<char> done(jobs.size(), 0);
    for (uint32_t r = 0; r < h.count; ++r) {
      ppe::wire::ResultRecord rec;
      const unsigned char* bodies = nullptr;
      ASSERT_TRUE(ppe::wire::next_result(back_.data(), back_.size(), offset, rec, bodies));
      const uint32_t k = rec.job;
      if (k >= jobs.size() || done[k]) continue;
      done[k] = 1;
      const std::string why =
          ppe::wire::decode_result(rec, bodies, jobs[k].image, jobs[k].result, jobs[k].result_capacity, reports[k]);
      if (!why.empty()) refuse(jobs[k], reports[k]);
    }
    EXPECT_EQ(offset, back_.size());
    for (uint32_t k = 0; k < jobs.size(); ++k)
      if (!done[k]) refuse(jobs[k], reports[k]);
  }
  ppe::TransportCounters last_transport() const override { return last_; }
  const char* name() const override { return "loopback"; }

 private:
  void refuse(const spu::IslandJob& j, spu::IslandReport& r) {
    ++last_.bad_messages;
    std::memset(j.result, 0, sizeof(gen::Island_Result));
    r.status = spu::IslandStatus::malformed;
  }
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
  uint32_t recomputed = 0, bad = 0, islands = 0, batches = 0;
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
  t.batches = loop->batches;
}

TEST(MpiWire, LoopbackEqualsWorkerPoolBitForBit) {
  for (const char* name : {"pile65", "world1000"}) {
    Totals t;
    same_as_pool(name, 45, -1, t);
    ASSERT_GT(t.bodies, 0u);
    EXPECT_EQ(t.recomputed, 0u);
    // out: the compressed table (with each island's shared records), a 16-byte record header
    // per island and a 32-byte batch header per wave
    const uint64_t batch = sizeof(ppe::wire::BatchHeader);
    EXPECT_EQ(t.to, t.table_out + sizeof(ppe::wire::JobRecord) * t.islands + batch * t.batches);
    // back: exactly 13 floats per body, a 48-byte record per island, a batch header per wave
    EXPECT_EQ(t.table_back, 52u * t.bodies);
    EXPECT_EQ(t.from, t.table_back + sizeof(ppe::wire::ResultRecord) * t.islands + batch * t.batches);
    EXPECT_LT(t.batches * 4, t.islands) << name << ": several islands a batch";
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

// A batch of three one-body islands; the middle one's job record is damaged on the way.
TEST(MpiWire, DamagedJobIsRefusedByTheNodeAndTheOthersAnswered) {
  std::vector<std::vector<unsigned char>> images;
  for (int i = 0; i < 3; ++i) {
    spu::IslandBuilder ib;
    gen::Rigid_Body_Fields f;
    f.mass = 1.0f;
    f.inverse_mass = 1.0f;
    f.position[1] = 1.0f + float(i);
    for (int k = 0; k < 3; ++k) f.inertia_body[k] = 0.1f, f.inverse_inertia_body[k] = 10.0f;
    ib.add_body(f);
    images.push_back(ib.finish());
  }
  std::vector<unsigned char> msg, back;
  ppe::wire::begin_batch(ppe::wire::kJobsMagic, 1, 256 * 1024, msg);
  std::vector<size_t> ends;
  for (uint32_t k = 0; k < 3; ++k) {
    ppe::wire::append_job(images[k].data(), images[k].size(), k, msg);
    ends.push_back(msg.size());
  }
  ppe::wire::seal_batch(msg);
  msg[ends[1] - 5] ^= 0x80;  // inside job 1's contact/force tail or bodies
  ppe::wire::NodeKernel node;
  node.serve(msg.data(), msg.size(), back);
  EXPECT_EQ(node.islands(), 2u);
  ASSERT_EQ(node.record_offsets().size(), 3u);
  ppe::wire::BatchHeader h;
  ASSERT_EQ(ppe::wire::decode_batch_header(back.data(), back.size(), ppe::wire::kResultsMagic, h), "");
  size_t offset = sizeof h;
  for (uint32_t k = 0; k < 3; ++k) {
    ppe::wire::ResultRecord rec;
    const unsigned char* bodies = nullptr;
    ASSERT_TRUE(ppe::wire::next_result(back.data(), back.size(), offset, rec, bodies));
    ASSERT_EQ(rec.job, k);
    std::vector<unsigned char> result(spu::result_bytes(1));
    spu::IslandReport r;
    const std::string why = ppe::wire::decode_result(rec, bodies, images[k].data(), result.data(), result.size(), r);
    EXPECT_EQ(why, "");
    if (k == 1) EXPECT_EQ(r.status, spu::IslandStatus::malformed) << "a damaged job must not come back as sound";
    else EXPECT_NE(r.status, spu::IslandStatus::malformed) << "a sound job of the same batch is answered";
  }
  // a damaged batch header: nothing is answered, so the dispatcher recomputes every island
  msg[8] ^= 0x01;
  node.serve(msg.data(), msg.size(), back);
  EXPECT_EQ(ppe::wire::decode_batch_header(back.data(), back.size(), ppe::wire::kResultsMagic, h), "");
  EXPECT_EQ(h.count, 0u);
}

}  // namespace

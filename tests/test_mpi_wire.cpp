// The compute-node messages without MPI: a loopback runner ships every island through the
// wire codec (runtime/ppe/wire.h) to a node kernel in this process, so the world's results
// must equal the worker pool's bit for bit, and damage on the way must be caught and the
// island recomputed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

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
  // edits the answer (its bytes, where each result record starts) before it is decoded
  std::function<void(std::vector<unsigned char>&, const std::vector<size_t>&)> tamper;
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
    if (tamper) tamper(back_, at);
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

void same_as_pool(const char* name, int steps, int corrupt_at, Totals& t,
                  std::function<void(std::vector<unsigned char>&, const std::vector<size_t>&)> tamper = {}) {
  auto a = scene(name), b = scene(name);
  auto loop = std::make_shared<LoopbackRunner>();
  loop->corrupt_at = corrupt_at;
  loop->tamper = std::move(tamper);
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

// n packed islands of one falling body each.
std::vector<std::vector<unsigned char>> one_body_islands(int n) {
  std::vector<std::vector<unsigned char>> images;
  for (int i = 0; i < n; ++i) {
    spu::IslandBuilder ib;
    gen::Rigid_Body_Fields f;
    f.mass = 1.0f;
    f.inverse_mass = 1.0f;
    f.position[1] = 1.0f + float(i);
    f.orientation[0] = 1.0f;
    for (int k = 0; k < 3; ++k) f.inertia_body[k] = 0.1f, f.inverse_inertia_body[k] = 10.0f;
    ib.add_body(f);
    images.push_back(ib.finish());
  }
  return images;
}

// A jobs batch of the images, sealed, for a kernel of `local_store` bytes.
std::vector<unsigned char> jobs_batch(const std::vector<std::vector<unsigned char>>& images, uint64_t local_store) {
  std::vector<unsigned char> msg;
  ppe::wire::begin_batch(ppe::wire::kJobsMagic, 1, local_store, msg);
  for (uint32_t k = 0; k < images.size(); ++k) ppe::wire::append_job(images[k].data(), images[k].size(), k, msg);
  ppe::wire::seal_batch(msg);
  return msg;
}

// A batch of three one-body islands; the middle one's job record is damaged on the way.
TEST(MpiWire, DamagedJobIsRefusedByTheNodeAndTheOthersAnswered) {
  const std::vector<std::vector<unsigned char>> images = one_body_islands(3);
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

// Found by fuzz_node: a sealed batch naming a local store no kernel can have (0, or over
// LocalStore's 1 GiB) threw out of the node's LocalStore constructor and ended the node. It is
// a damaged header now: no island is answered, so the dispatcher recomputes them all.
TEST(MpiWire, LocalStoreOutOfRangeIsADamagedHeaderNotAnException) {
  const std::vector<std::vector<unsigned char>> images = one_body_islands(2);
  ppe::wire::NodeKernel node;
  std::vector<unsigned char> back;
  for (uint64_t bytes : {uint64_t{0}, uint64_t{spu::LocalStore::kMinCapacity - 1}, uint64_t{spu::LocalStore::kMaxCapacity + 1},
                         uint64_t{1} << 62}) {
    const std::vector<unsigned char> msg = jobs_batch(images, bytes);
    ASSERT_NO_THROW(node.serve(msg.data(), msg.size(), back)) << bytes;
    ppe::wire::BatchHeader h;
    ASSERT_EQ(ppe::wire::decode_batch_header(back.data(), back.size(), ppe::wire::kResultsMagic, h), "");
    EXPECT_EQ(h.count, 0u) << bytes;
  }
  EXPECT_EQ(node.islands(), 0u);
  const std::vector<unsigned char> msg = jobs_batch(images, spu::LocalStore::kMinCapacity);
  node.serve(msg.data(), msg.size(), back);
  EXPECT_EQ(node.record_offsets().size(), 2u) << "the smallest local store is in range";
}

// Seals a result record again after an edit (the checksum wire.cpp computes: the record with
// the field zero, then its bodies), so that only the edit is wrong.
void seal_result(std::vector<unsigned char>& back, size_t at) {
  ppe::wire::ResultRecord r;
  std::memcpy(&r, back.data() + at, sizeof r);
  r.checksum = 0;
  r.checksum = spu::checksum(back.data() + at + sizeof r, size_t{r.num_bodies} * sizeof(gen::Wire_Node_To_Dispatcher),
                             spu::checksum(reinterpret_cast<const unsigned char*>(&r), sizeof r));
  std::memcpy(back.data() + at, &r, sizeof r);
}

// Found by fuzz_dispatcher: an answer whose checksum matched but whose bodies were not finite
// (a node that computed garbage, or was built wrong) was taken, and NaN entered the world.
// Each body's returned state must be finite with a unit quaternion; otherwise the island is
// refused by body and field and recomputed.
TEST(MpiWire, NonFiniteReturnedStateIsRefusedAndRecomputed) {
  const std::vector<std::vector<unsigned char>> images = one_body_islands(1);
  const std::vector<unsigned char> msg = jobs_batch(images, 256 * 1024);
  ppe::wire::NodeKernel node;
  std::vector<unsigned char> good;
  node.serve(msg.data(), msg.size(), good);
  const size_t body = sizeof(ppe::wire::BatchHeader) + sizeof(ppe::wire::ResultRecord);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  struct Case {
    size_t offset;  // in the body record: position 0, orientation 12, velocity 28, angular velocity 40
    float value;
    const char* why;
  };
  for (const Case& c : {Case{4, nan, "body 0: position[1] is not finite"}, Case{28, inf, "body 0: velocity[0] is not finite"},
                        Case{48, -inf, "body 0: angular velocity[2] is not finite"},
                        Case{12, 2.0f, "body 0: orientation is not a unit quaternion"}}) {
    std::vector<unsigned char> back = good;
    std::memcpy(back.data() + body + c.offset, &c.value, 4);
    seal_result(back, sizeof(ppe::wire::BatchHeader));
    std::vector<unsigned char> result(spu::result_bytes(1));
    std::vector<spu::IslandJob> jobs = {{images[0].data(), images[0].size(), result.data(), result.size()}};
    std::vector<spu::IslandReport> reports(1);
    std::string got = "(not answered)";
    const std::string rest = ppe::wire::read_results(
        back.data(), back.size(), 1, jobs, reports, [](uint32_t) { return true; },
        [&](uint32_t, const std::string& why) { got = why; });
    EXPECT_EQ(got, c.why);
    EXPECT_EQ(rest, "no sound result in the node's answer");
  }
  // through a world: every tenth island of world1000 comes back with a NaN velocity
  Totals t;
  same_as_pool("world1000", 3, -1, t, [&](std::vector<unsigned char>& back, const std::vector<size_t>& at) {
    for (size_t i = 0; i < at.size(); i += 10) {
      std::memcpy(back.data() + at[i] + sizeof(ppe::wire::ResultRecord) + 28, &nan, 4);
      seal_result(back, at[i]);
    }
  });  // hashes compared every step inside
  EXPECT_GT(t.recomputed, 10u);
}

}  // namespace

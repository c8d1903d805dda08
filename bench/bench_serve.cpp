// What serving costs, per tick, on the world1000 scene while half its bodies fall (docs/server.md):
// publishing a frame from the world, encoding a tick at full precision and quantised (bytes per
// body against the wire table's 13 floats), and encoding for 1, 10 and 100 clients that watch
// every body (one shared encoding) or each a region of their own (one encoding each).
#include <benchmark/benchmark.h>

#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "runtime/scene/scene.h"
#include "server/room.h"
#include "server/state_encoder.h"

namespace {

using namespace cellphys;

// Two consecutive frames of world1000 30 steps in (bodies falling), as a room publishes them.
struct Frames {
  std::shared_ptr<server::Frame> before, after;
  std::vector<uint32_t> ids;
};

std::shared_ptr<server::Frame> frame_of(const ppe::World& w, uint64_t seq) {
  auto f = std::make_shared<server::Frame>();
  f->seq = seq;
  f->step = w.last_stats().step;
  for (ppe::BodyId id : w.bodies()) {
    server::FrameBody b;
    b.id = id;
    b.shape = w.shape(id);
    b.scale = w.scale(id);
    b.state = w.state(id);
    b.flags = w.is_awake(id) ? server::protocol::kBodyAwake : 0u;
    b.changed = seq;
    f->bodies.push_back(b);
  }
  return f;
}

const Frames& frames() {
  static const Frames fr = [] {
    auto built = scene::build_world(scene::load_scene(std::string(CELLPHYS_SCENES_DIR) + "/world1000.json"));
    ppe::World& w = *built.world;
    for (int i = 0; i < 30; ++i) w.step();
    Frames f;
    f.before = frame_of(w, 1);
    w.step();
    f.after = frame_of(w, 2);
    // A body whose state did not change keeps its older seq (it is not moved).
    for (size_t i = 0; i < f.after->bodies.size(); ++i)
      if (std::memcmp(&f.after->bodies[i].state, &f.before->bodies[i].state, sizeof(ppe::BodyState)) == 0)
        f.after->bodies[i].changed = 1;
    for (const auto& b : f.before->bodies) f.ids.push_back(b.id);
    return f;
  }();
  return fr;
}

void BM_EncodeTick(benchmark::State& state) {
  const Frames& f = frames();
  server::Interest in;
  in.quantised = state.range(0) != 0;
  std::vector<unsigned char> out;
  size_t moved = 0;
  for (auto _ : state) {
    out.clear();
    std::vector<uint32_t> known = f.ids;
    server::encode_tick(*f.after, in, 1, 0, known, out);
    benchmark::DoNotOptimize(out.data());
  }
  for (const auto& b : f.after->bodies) moved += b.changed == 2;
  state.counters["bytes"] = double(out.size());
  state.counters["moved_bodies"] = double(moved);
  state.counters["bytes_per_moved_body"] = double(out.size() - sizeof(server::protocol::Tick)) / double(moved);
  state.counters["wire_table_bytes_per_body"] = 13 * 4;
  state.SetLabel(in.quantised ? "quantised" : "full");
}
BENCHMARK(BM_EncodeTick)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// One tick for N clients: all watching every body (the frame's shared encoding, as WsSession
// does) or each a region of its own (a quarter of the world's width, one encoding each).
void BM_EncodeForClients(benchmark::State& state) {
  const Frames& f = frames();
  const int clients = static_cast<int>(state.range(0));
  const bool regions = state.range(1) != 0;
  size_t bytes = 0;
  for (auto _ : state) {
    state.PauseTiming();
    auto frame = std::make_shared<server::Frame>();  // a fresh frame: nothing cached
    frame->seq = f.after->seq;
    frame->bodies = f.after->bodies;
    state.ResumeTiming();
    bytes = 0;
    for (int c = 0; c < clients; ++c) {
      std::vector<uint32_t> known = f.ids;
      if (regions) {
        server::Interest in;
        in.region = true;
        const float x0 = -40.0f + 20.0f * float(c % 4);
        const float lo[3] = {x0, -40, -1}, hi[3] = {x0 + 20, 40, 100};
        std::copy(lo, lo + 3, in.min);
        std::copy(hi, hi + 3, in.max);
        std::vector<unsigned char> out;
        server::encode_tick(*frame, in, 1, 0, known, out);
        bytes += out.size();
      } else {
        bytes += server::shared_tick(*frame, false, 1, known)->size();
      }
    }
  }
  state.counters["clients"] = clients;
  state.counters["bytes_out"] = double(bytes);
  state.SetLabel(regions ? "a region each" : "every body, shared encoding");
}
BENCHMARK(BM_EncodeForClients)
    ->ArgsProduct({{1, 10, 100}, {0, 1}})
    ->Unit(benchmark::kMicrosecond);

// What a room does after each step before any client: the frame of every body's state.
void BM_PublishFrame(benchmark::State& state) {
  auto built = scene::build_world(scene::load_scene(std::string(CELLPHYS_SCENES_DIR) + "/world1000.json"));
  ppe::World& w = *built.world;
  for (int i = 0; i < 30; ++i) w.step();
  uint64_t seq = 0;
  for (auto _ : state) benchmark::DoNotOptimize(frame_of(w, ++seq));
}
BENCHMARK(BM_PublishFrame)->Unit(benchmark::kMicrosecond);

}  // namespace

#include "server/frame_builder.h"

#include <cstring>

#include "server/stages_encoder.h"

namespace cellphys::server {

std::shared_ptr<Frame> build_frame(const ppe::World& w, const FrameContext& at, const Frame* prev) {
  auto f = std::make_shared<Frame>();
  f->world = at.world;
  f->seq = at.seq;
  f->step = w.last_stats().step;
  f->epoch = at.epoch;
  f->paused = at.paused;
  f->dt = w.settings().dt;
  f->tick_hz = at.tick_hz;
  f->state_hash = w.state_hash();
  const ppe::StepStats& st = w.last_stats();
  f->stats = protocol::TickStats{static_cast<float>(at.step_ms), st.active_bodies, st.sleeping_bodies, st.contacts,
                                 st.islands, st.solver_iterations, st.failed_islands, st.step_halvings};
  f->stages = std::make_shared<const std::vector<unsigned char>>(encode_stages(f->step, at.epoch, st.times));
  f->shapes = at.shapes;
  f->num_shapes = static_cast<uint32_t>(w.shapes().size());
  const bool same_epoch = prev && prev->epoch == at.epoch;
  const std::vector<ppe::BodyId> ids = w.bodies();
  f->bodies.reserve(ids.size());
  size_t k = 0;
  for (ppe::BodyId id : ids) {
    FrameBody b;
    b.id = id;
    b.shape = w.shape(id);
    b.scale = w.scale(id);
    b.state = w.state(id);
    b.flags = (w.is_awake(id) ? protocol::kBodyAwake : 0u) | (w.is_static(id) ? protocol::kBodyStatic : 0u) |
              (w.shapes().is_static_infinite(b.shape) ? protocol::kBodyUnbounded : 0u);
    b.changed = f->seq;
    if (same_epoch) {
      while (k < prev->bodies.size() && prev->bodies[k].id < id) ++k;
      if (k < prev->bodies.size() && prev->bodies[k].id == id) {
        const FrameBody& p = prev->bodies[k];
        if (std::memcmp(&p.state, &b.state, sizeof b.state) == 0) b.changed = p.changed;  // moved: its state's bits
      }
    }
    f->bodies.push_back(b);
  }
  return f;
}

}  // namespace cellphys::server

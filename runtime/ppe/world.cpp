#include "runtime/ppe/world.h"

#include <algorithm>
#include <cassert>
#include <chrono>

#include "runtime/ppe/body_maths.h"
#include "runtime/ppe/settings.h"
#include "runtime/ppe/step_collide.h"
#include "runtime/ppe/step_decouple.h"
#include "runtime/ppe/step_events.h"
#include "runtime/ppe/step_integrate.h"
#include "runtime/ppe/step_islands.h"
#include "runtime/ppe/step_project.h"
#include "runtime/ppe/step_push.h"
#include "runtime/ppe/step_sleep.h"
#include "runtime/ppe/world_checks.h"
#include "runtime/ppe/world_impl.h"

namespace cellphys::ppe {

using namespace cellphys::gen;

namespace {

// A checked state into a body: the orientation normalised (with a warning when it was not
// unit); a static body keeps zero velocities.
void take_state(const BodyState& s, const std::string& who, std::vector<std::string>& warnings, WorldBody& b) {
  std::copy(s.position, s.position + 3, b.state.position);
  normalise_orientation(s.orientation, b.state.orientation, who, warnings);
  if (b.is_static) return;
  std::copy(s.velocity, s.velocity + 3, b.state.velocity);
  std::copy(s.angular_velocity, s.angular_velocity + 3, b.state.angular_velocity);
}

}  // namespace

World::World(WorldSettings settings) : settings_(settings), impl_(std::make_unique<Impl>()) {
  validate_settings(settings_);
}
World::~World() = default;

void World::set_runner(std::shared_ptr<IslandRunner> runner) { impl_->runner = std::move(runner); }
IslandRunner* World::runner() const { return impl_->runner.get(); }

void World::set_settings(const WorldSettings& s) {
  validate_settings(s);
  settings_ = s;
  impl_->sleeping.all_changed = true;  // boxes grow by the margins, the region culls
}

BodyId World::add_body(const BodyDesc& d) {
  warnings_.clear();
  const std::string who = body_name(static_cast<BodyId>(impl_->bodies.size()));
  const bool is_static = d.is_static || (d.shape < shapes_.size() && shapes_.is_static_only(d.shape));
  check_body_desc(shapes_, d, is_static, who);
  WorldBody b;
  b.alive = true;
  b.shape = d.shape;
  b.scale = d.scale;
  b.friction = d.friction;
  b.linear_damping = d.linear_damping;
  b.angular_damping = d.angular_damping;
  b.is_static = is_static;
  b.sensor = d.sensor;
  take_state(d.state, who, warnings_, b);
  if (!b.is_static) set_mass_properties(shapes_, d, who, b);
  impl_->bodies.push_back(b);
  ++impl_->revision;
  impl_->changed(static_cast<BodyId>(impl_->bodies.size() - 1));
  return static_cast<BodyId>(impl_->bodies.size() - 1);
}

void World::remove_body(BodyId id) {
  WorldBody& b = impl_->live(id);
  impl_->wake(id);
  for (WorldForce& f : impl_->forces)
    if (f.alive && (f.a == id || f.b == id)) {
      if (f.a != id) impl_->wake(f.a);
      if (f.b != id && f.b != kWorldBody) impl_->wake(f.b);
      f.alive = false;
    }
  forget_body(impl_->contact_memory, id);
  end_events_of(impl_->event_memory, id);
  b.alive = false;
  impl_->changed(id);
  ++impl_->revision;
}

ForceId World::add_force(const std::string& type, BodyId a, BodyId b, const ForceParams& params) {
  warnings_.clear();
  const ForceInfo& info = force_type_info(type);
  const WorldBody& ba = impl_->live(a);
  if (ba.is_static) throw WorldError("force " + type + ": body a (" + body_name(a) + ") is static");
  if (info.kind == ForceKind::binary) {
    if (b == kWorldBody) {
      if (!info.world_anchor) throw WorldError("force " + type + " cannot be anchored to the world");
    } else {
      const WorldBody& bb = impl_->live(b);
      if (b == a) throw WorldError("force " + type + ": a and b are the same body");
      if (bb.is_static) throw WorldError("force " + type + ": body b (" + body_name(b) + ") is static; use \"world\"");
    }
  } else if (b != kWorldBody) {
    throw WorldError("force " + type + " acts on one body: b must be the world");
  }
  WorldForce f;
  f.alive = true;
  f.type = info.type;
  f.a = a;
  f.b = info.kind == ForceKind::binary ? b : kWorldBody;
  f.instance.assign(info.instance_size, 0);
  set_force_params(info, params, f.instance);
  impl_->wake(a);
  if (f.b != kWorldBody) impl_->wake(f.b);
  impl_->forces.push_back(std::move(f));
  return static_cast<ForceId>(impl_->forces.size() - 1);
}

void World::remove_force(ForceId id) {
  if (id >= impl_->forces.size() || !impl_->forces[id].alive) throw WorldError("force " + std::to_string(id) + " does not exist");
  WorldForce& f = impl_->forces[id];
  impl_->wake(f.a);
  if (f.b != kWorldBody) impl_->wake(f.b);
  f.alive = false;
}

BodyState World::state(BodyId id) const {
  return impl_->live(id).state;
}

void World::set_state(BodyId id, const BodyState& s) {
  warnings_.clear();
  WorldBody& b = impl_->live(id);
  check_body_state(s, body_name(id));
  take_state(s, body_name(id), warnings_, b);
  impl_->wake(id);
  impl_->changed(id);
  ++impl_->revision;
}

void World::apply_impulse(BodyId id, const float impulse[3], const float point[3]) {
  WorldBody& b = impl_->live(id);
  check_impulse(impulse, point, body_name(id));
  if (b.is_static) throw WorldError(body_name(id) + " is static");
  impl_->wake(id);
  ppe::apply_impulse(b, impulse, point);
}

bool World::is_awake(BodyId id) const { return impl_->live(id).awake; }
bool World::is_static(BodyId id) const { return impl_->live(id).is_static; }
bool World::is_sensor(BodyId id) const { return impl_->live(id).sensor; }
const std::vector<ContactEvent>& World::contact_events() const { return impl_->contact_events; }
const std::vector<SensorEvent>& World::sensor_events() const { return impl_->sensor_events; }

std::vector<BodyId> World::sensor_contents(BodyId sensor) const {
  if (!impl_->live(sensor).sensor) throw WorldError(body_name(sensor) + " is not a sensor");
  std::vector<BodyId> inside;
  for (uint64_t k : impl_->event_memory.sensing)
    if (uint32_t(k >> 32) == sensor) inside.push_back(uint32_t(k));
  return inside;
}
bool World::has_body(BodyId id) const { return id < impl_->bodies.size() && impl_->bodies[id].alive; }
uint32_t World::shape(BodyId id) const { return impl_->live(id).shape; }
float World::scale(BodyId id) const { return impl_->live(id).scale; }
float World::mass(BodyId id) const { return impl_->live(id).mass; }
const float* World::inertia_body(BodyId id) const { return impl_->live(id).inertia; }

std::vector<BodyId> World::bodies() const {
  std::vector<BodyId> ids;
  for (BodyId i = 0; i < impl_->bodies.size(); ++i)
    if (impl_->bodies[i].alive) ids.push_back(i);
  return ids;
}

size_t World::num_bodies() const {
  return static_cast<size_t>(std::count_if(impl_->bodies.begin(), impl_->bodies.end(), [](const WorldBody& b) { return b.alive; }));
}

double World::kinetic_energy() const {
  double e = 0;
  for (const WorldBody& b : impl_->bodies)
    if (b.alive && !b.is_static) add_kinetic_energy(b, e);
  return e;
}

uint64_t World::state_hash() const {
  uint64_t h = 0xCBF29CE484222325ull;
  for (const WorldBody& b : impl_->bodies)
    if (b.alive) h = hash_state(b, h);
  return h;
}

// The stages in order; each times itself into stats.times under its name.
const StepStats& World::step() {
  Impl& w = *impl_;
  StepStats st;
  st.step = stats_.step + 1;
  // Its threads ready for each stage's tasks, unless no body may be awake (none was, and none
  // changed set since): such a step hands out no work, and waking the threads for it doubled
  // its cost on 2 workers. (A threshold of awake bodies below which a step would run alone was
  // measured and not kept: at 100 bodies two threads were 1.3x faster in one sitting of this
  // machine and 15% slower in another; docs/bench.md, "Worker scaling".)
  const bool may_work = w.sleeping.all_changed || !w.awake.ids().empty() || !w.sleeping.changed.empty();
  WorkerPool::Hold hold(w.workers(settings_), may_work);
  st.stage_end = std::chrono::steady_clock::now();  // the first stage starts here
  {
    StageTimer total(st, &StageTimes::total_ms);
    // The bodies that changed set since the last step; those stage 2 wakes join after it.
    const bool all = w.sleeping.all_changed;
    w.awake.update(w.bodies, w.sleeping.changed, all);
    assert(w.awake.agrees_with(w.bodies));
    w.step_changed.swap(w.sleeping.changed);
    w.sleeping.changed.clear();
    w.sleeping.all_changed = false;
    const BodyChanges changes{w.awake.ids(), w.step_changed, all};
    collide(w.bodies, w.forces, shapes_, settings_, changes, &w.workers(settings_), w.collide, w.contact_memory,  // 1
            w.contacts, st);
    PendingEvents& events = w.pending_events;  // 8, begun: what a touch's begin measures before the step moves anything
    {
      StageTimer t(st, &StageTimes::events_ms);
      begin_events(w.bodies, shapes_, settings_, w.collide.woken, all, w.collide.reach, w.contacts, w.collide.touched,
                   w.collide.sensed, w.event_memory, w.sensor_events, events);
    }
    wake_touched_groups(w.bodies, w.forces, w.contacts, w.sleeping, st);                 // 2
    w.awake.update(w.bodies, w.sleeping.changed, false);
    push_out_overlaps(settings_, w.forces, w.bodies, w.contacts, w.contact_memory, w.push, st);  // 3
    build_islands(w.bodies, w.forces, w.contacts, w.awake, w.island_scratch, st, w.islands);  // 4
    const std::vector<IslandContent>& islands = w.islands;
    decouple_islands(PackContext{w.bodies, w.forces, w.contacts, settings_, w.bodies}, islands,  // 5
                     w.islands_runner(settings_).whole_island_bytes(), st,
                     w.integrate.pack, w.parts);
    const DecoupledIslands& parts = w.parts;
    integrate_islands(settings_, shapes_, islands, parts, w.forces, w.contacts, w.bodies,  // 6
                      w.compute(settings_), w.integrate, w.failed, st);
    {
      StageTimer t(st, &StageTimes::integrate_ms);  // the end of integration: joints opened too far
      project_joints(settings_, w.forces, w.bodies, st);
      note_held_gaps(w.bodies, settings_, w.contacts, w.contact_memory);
    }
    const std::vector<uint8_t>& failed = w.failed;
    sleep_quiet_islands(settings_, islands, failed, w.contacts, w.bodies, w.sleeping, st);  // 7
    {
      StageTimer t(st, &StageTimes::events_ms);  // 8, finished: the begin touches' impulses
      finish_events(w.bodies, events, w.event_memory, w.contact_events);
    }
    // Which island each body was in, for last_island (display only): the last step's entries
    // cleared, not every body's (a step costs what is awake).
    for (uint32_t id : w.island_listed) w.island_of[id] = kNoIsland;
    w.island_listed.clear();
    w.island_of.resize(w.bodies.size(), kNoIsland);
    w.island_decoupled.assign(islands.size(), 0);
    for (size_t i = 0; i < islands.size(); ++i) {
      for (uint32_t id : islands[i].bodies) w.island_of[id] = static_cast<uint32_t>(i), w.island_listed.push_back(id);
      w.island_decoupled[i] = i < parts.used.size() && parts.is_split(i);
    }
    cut_couplings_of(parts, w.contacts, w.forces, w.cut_ids, w.cut);
  }
  ++w.revision;
  stats_ = st;
  return stats_;
}

}  // namespace cellphys::ppe

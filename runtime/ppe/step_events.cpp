#include "runtime/ppe/step_events.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "runtime/base/merge_tail.h"
#include "runtime/base/quat.h"
#include "runtime/ppe/body_maths.h"
#include "runtime/ppe/contact_loads.h"
#include "runtime/spu/narrow_phase.h"

namespace cellphys::ppe {

namespace {

uint64_t key_of(uint32_t a, uint32_t b) { return uint64_t(a) << 32 | b; }
uint32_t high(uint64_t k) { return uint32_t(k >> 32); }
uint32_t low(uint64_t k) { return uint32_t(k); }

bool still(const std::vector<WorldBody>& bodies, uint32_t id) {
  return id < bodies.size() && bodies[id].alive && (bodies[id].is_static || !bodies[id].awake);
}
// A pair the step did not collide stays as it was while nothing of it moves.
bool kept(const std::vector<WorldBody>& bodies, uint64_t k) { return still(bodies, high(k)) && still(bodies, low(k)); }

Mat3d inverse_inertia_world(const WorldBody& b) {
  return rotate_sym(quat_to_matrix(Quatd::load(b.state.orientation)), b.inverse_inertia);
}

// 1 / (velocity change along n at p per unit impulse along n) of the pair; a static body adds nothing.
double effective_mass(const std::vector<WorldBody>& bodies, uint32_t a, uint32_t b, const Vec3d& p, const Vec3d& n) {
  double w = 0;
  for (uint32_t id : {a, b}) {
    const WorldBody& x = bodies[id];
    if (x.is_static) continue;
    w += inverse_mass_along(1.0 / x.mass, inverse_inertia_world(x), Vec3d::load(x.state.position), p, n);
  }
  return w > 0 ? 1.0 / w : 0.0;
}

Vec3d body_velocity_at(const std::vector<WorldBody>& bodies, uint32_t id, const Vec3d& p) {
  return bodies[id].is_static ? Vec3d{0, 0, 0} : velocity_at(bodies, id, p);
}

// Separating speed of b from a along n at p (> 0 apart).
double separating(const std::vector<WorldBody>& bodies, uint32_t a, uint32_t b, const Vec3d& p, const Vec3d& n) {
  return dot(body_velocity_at(bodies, b, p) - body_velocity_at(bodies, a, p), n);
}

void put3(float* out, const Vec3d& v) { out[0] = float(v.x), out[1] = float(v.y), out[2] = float(v.z); }

// A candidate's begin at the middle of the pair's points: the fastest closing speed among them,
// and the effective mass and the gravity-only separating speed at the middle, for the impulse.
PendingEvents::Candidate candidate(const std::vector<WorldBody>& bodies, const WorldSettings& s,
                                   const std::vector<WorldContact>& contacts, const TouchedPair& t) {
  PendingEvents::Candidate c{};
  Vec3d mid{0, 0, 0}, n{0, 0, 0};
  double fastest = 0;
  for (uint32_t i = t.first; i < t.first + t.count; ++i) {
    const spu::ContactPoint& cp = contacts[i].point;
    const Vec3d p = Vec3d::load(cp.point), ni = Vec3d::load(cp.normal);
    mid = mid + p;
    n = n + ni;
    const double closing = -separating(bodies, t.a, t.b, p, ni);
    fastest = std::max(fastest, closing);
    // as the contact decides it: the gap closes by the step's end, with gravity's fall (the
    // contact's a is the dynamic body: a static a is seen from the other side)
    const float from_b[3] = {-cp.normal[0], -cp.normal[1], -cp.normal[2]};
    const double fall = bodies[t.a].is_static ? gravity_fall(from_b, true, s) : gravity_fall(cp.normal, bodies[t.b].is_static, s);
    c.acts = c.acts || cp.penetration + s.dt * std::max(closing - fall, 0.0) >= 0.0;
  }
  if (!c.acts) return c;  // a speculative pair that does not close this step: nothing more to measure
  mid = mid * (1.0 / t.count);
  const double len = norm(n);
  n = len > 0 ? n * (1.0 / len) : Vec3d::load(contacts[t.first].point.normal);
  // Gravity alone would change the separating speed by h g.n for each dynamic body (a's from
  // the other side).
  const Vec3d g = Vec3d::load(s.globals.gravity);
  double free = separating(bodies, t.a, t.b, mid, n);
  if (!bodies[t.b].is_static) free += s.dt * dot(g, n);
  if (!bodies[t.a].is_static) free -= s.dt * dot(g, n);
  ContactEvent& e = c.begin;
  e.kind = ContactEvent::Kind::begin;
  e.a = t.a, e.b = t.b;
  if (e.a > e.b) std::swap(e.a, e.b), n = n * -1.0;  // the lower id first, as every event has it
  put3(e.point, mid);
  put3(e.normal, n);
  e.approach_speed = float(fastest);
  c.mass = float(effective_mass(bodies, t.a, t.b, mid, n));
  c.free_speed = float(free);
  return c;
}

// Whether a touching pair collision did not find is still coming at itself: within twice the
// margin collision used, a point closes.
bool still_closing(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                   const std::vector<float>& reach, uint64_t k) {
  uint32_t a = high(k), b = low(k);
  if (a >= bodies.size() || b >= bodies.size() || !bodies[a].alive || !bodies[b].alive) return false;
  if (bodies[a].is_static) std::swap(a, b);  // as collision orders a pair
  const float margin = 2 * (s.globals.contact_slop + reach[a] + reach[b]);
  spu::ContactPoint cp[spu::kMaxManifoldPoints];
  const int n = spu::collide(shapes.view(bodies[a].shape), pose_of(bodies[a]), shapes.view(bodies[b].shape),
                             pose_of(bodies[b]), margin, cp);
  for (int i = 0; i < n; ++i)
    if (separating(bodies, a, b, Vec3d::load(cp[i].point), Vec3d::load(cp[i].normal)) < 0) return true;
  return false;
}

// Keeps in `memory` (sorted) the keys found this step (`found`, sorted) and those `keep` says
// stay; the rest end. Each key kept is first offered to `aside`, which may take it.
template <class Keep, class Aside, class End>
void keep_or_end(const std::vector<uint64_t>& found, std::vector<uint64_t>& memory, Keep keep, Aside aside, End end) {
  auto f = found.begin();
  size_t out = 0;
  for (uint64_t k : memory) {
    while (f != found.end() && *f < k) ++f;
    const bool was_found = f != found.end() && *f == k;
    if (!was_found && aside(k)) continue;
    if (was_found || keep(k)) memory[out++] = k;
    else end(k);
  }
  memory.resize(out);
}

bool by_pair(const ContactEvent& x, const ContactEvent& y) {
  return std::make_tuple(x.a, x.b, x.kind) < std::make_tuple(y.a, y.b, y.kind);
}

}  // namespace

void begin_events(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                  const std::vector<uint32_t>& woken, bool all, const std::vector<float>& reach,
                  const std::vector<WorldContact>& contacts, const std::vector<TouchedPair>& touched,
                  const std::vector<std::pair<uint32_t, uint32_t>>& sensed, EventMemory& memory,
                  std::vector<SensorEvent>& sensor_events, PendingEvents& out) {
  // the ends of removed bodies' touches first; buffers swapped, not moved, so each keeps one
  out.events.clear();
  out.events.swap(memory.removed_touches);
  out.candidates.clear();
  sensor_events.clear();
  sensor_events.swap(memory.removed_overlaps);

  // Touches: what touched and still collides, what sleeps as it was (set aside until a body of
  // it wakes); what collides anew may begin. One pass over the memory against this step's
  // pairs, sorted: a step costs what is awake.
  {
    std::vector<uint64_t>& back = memory.back;
    back.clear();
    if (all) back = memory.resting.keys(), memory.resting.clear();
    else memory.resting.take(woken, back);
    std::sort(back.begin(), back.end());
    merge_sorted_into(memory.touching, back, memory.found);  // (found is filled after)
  }
  std::vector<uint64_t>& found = memory.found;
  found.clear();
  // The pairs come in pair order, so their keys mostly ascend: the memory is walked along with
  // them (searched again only where a key goes back), not searched for each.
  const std::vector<uint64_t>& touching = memory.touching;
  auto at = touching.begin();
  for (const TouchedPair& t : touched) {
    const uint64_t k = key_of(std::min(t.a, t.b), std::max(t.a, t.b));
    found.push_back(k);
    if (at != touching.begin() && *(at - 1) >= k) at = std::lower_bound(touching.begin(), touching.end(), k);
    while (at != touching.end() && *at < k) ++at;
    if (at == touching.end() || *at != k) out.candidates.push_back(candidate(bodies, s, contacts, t));
  }
  // in pair order the keys ascend, so mostly there is nothing to sort
  if (!std::is_sorted(found.begin(), found.end())) std::sort(found.begin(), found.end());
  std::vector<uint64_t>& resting = memory.resting_now;
  resting.clear();
  const auto aside = [&](uint64_t k) { return kept(bodies, k) && (resting.push_back(k), true); };
  const auto closing = [&](uint64_t k) { return still_closing(bodies, shapes, s, reach, k); };
  keep_or_end(found, memory.touching, closing, aside, [&](uint64_t k) {
    ContactEvent e{};
    e.kind = ContactEvent::Kind::end;
    e.a = high(k), e.b = low(k);
    out.events.push_back(e);
  });
  memory.resting.add(resting);

  // Sensor overlaps, the same way; an overlap begins as soon as it is found (no force acts).
  found.clear();
  for (const auto& [sensor, visitor] : sensed) found.push_back(key_of(sensor, visitor));
  std::sort(found.begin(), found.end());
  keep_or_end(found, memory.sensing, [&](uint64_t k) { return kept(bodies, k); }, [](uint64_t) { return false; },
              [&](uint64_t k) { sensor_events.push_back({SensorEvent::Kind::end, high(k), low(k)}); });
  const size_t kept_overlaps = memory.sensing.size();
  for (uint64_t k : found)
    if (!std::binary_search(memory.sensing.begin(), memory.sensing.begin() + kept_overlaps, k)) {
      memory.sensing.push_back(k);
      sensor_events.push_back({SensorEvent::Kind::begin, high(k), low(k)});
    }
  merge_tail(memory.sensing, kept_overlaps, memory.back);
  std::sort(sensor_events.begin(), sensor_events.end(), [](const SensorEvent& x, const SensorEvent& y) {
    return std::make_tuple(x.sensor, x.visitor, x.kind) < std::make_tuple(y.sensor, y.visitor, y.kind);
  });
}

void finish_events(const std::vector<WorldBody>& bodies, PendingEvents& pending,
                   EventMemory& memory, std::vector<ContactEvent>& events) {
  events.clear();
  events.swap(pending.events);
  const size_t kept = memory.touching.size();
  for (PendingEvents::Candidate& c : pending.candidates) {
    if (!c.acts) continue;
    ContactEvent& e = c.begin;
    // The contact's impulse along the normal: what the step changed the separating speed by
    // beyond gravity's change, and what stops the approach still left at its end (a fast pair
    // arrives at the surface in this step and stops in the next), times the pair's effective
    // mass there.
    const double after = separating(bodies, e.a, e.b, Vec3d::load(e.point), Vec3d::load(e.normal));
    e.impulse = float(std::max(0.0, double(c.mass) * (std::max(after, 0.0) - c.free_speed)));
    events.push_back(e);
    memory.touching.push_back(key_of(e.a, e.b));
  }
  std::sort(memory.touching.begin() + kept, memory.touching.end());
  merge_tail(memory.touching, kept, memory.found);  // (the begin stage's buffers are free by now)
  std::sort(events.begin(), events.end(), by_pair);
}

void end_events_of(EventMemory& memory, uint32_t id) {
  auto split = [&](std::vector<uint64_t>& keys, auto emit) {
    keys.erase(std::remove_if(keys.begin(), keys.end(),
                              [&](uint64_t k) {
                                if (high(k) != id && low(k) != id) return false;
                                emit(k);
                                return true;
                              }),
               keys.end());
  };
  const auto end_touch = [&](uint64_t k) {
    ContactEvent e{};
    e.kind = ContactEvent::Kind::end;
    e.a = high(k), e.b = low(k);
    memory.removed_touches.push_back(e);
  };
  split(memory.touching, end_touch);
  std::vector<uint64_t> resting;
  memory.resting.take({id}, resting);
  for (uint64_t k : resting) end_touch(k);
  split(memory.sensing, [&](uint64_t k) { memory.removed_overlaps.push_back({SensorEvent::Kind::end, high(k), low(k)}); });
}

std::vector<uint64_t> touching_pairs(const EventMemory& memory) {
  std::vector<uint64_t> all = memory.touching;
  const size_t awake = all.size();
  all.insert(all.end(), memory.resting.keys().begin(), memory.resting.keys().end());
  std::inplace_merge(all.begin(), all.begin() + awake, all.end());
  return all;
}

}  // namespace cellphys::ppe

#include "runtime/ppe/step_push.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "cellphys/gen/force_table.h"
#include "runtime/base/vec3.h"
#include "runtime/ppe/contact_memory.h"
#include "runtime/ppe/world.h"

namespace cellphys::ppe {

namespace {

constexpr int kMaxSweeps = 32;
constexpr int32_t kFixed = -1;       // the world, a static or a sleeping body
constexpr int32_t kFree = INT_MAX;   // a body no chain of contacts joins to anything fixed
constexpr uint32_t kNone = 0xFFFFFFFFu;  // a body the stage has not numbered
// A contact within 60 degrees of vertical moves only the body above: a box is lifted off its
// support, not pressed into it. Flatter ones share by inverse mass (a box squeezed between
// two on the ground moves them apart).
constexpr double kUpCosine = 0.5;

}  // namespace

void push_out_overlaps(const WorldSettings& s, const std::vector<WorldForce>& forces, std::vector<WorldBody>& bodies,
                       std::vector<WorldContact>& contacts, ContactMemory& memory, PushScratch& p, StepStats& st) {
  StageTimer timer(st, &StageTimes::push_ms);
  const double budget = double(s.globals.contact_push_speed) * s.dt;
  if (budget <= 0) return;
  if (std::none_of(contacts.begin(), contacts.end(), [&](const WorldContact& c) { return c.point.penetration > c.hold; }))
    return;
  const uint32_t n = static_cast<uint32_t>(bodies.size());
  auto movable = [&](uint32_t b) { return b != kWorldBody && !bodies[b].is_static && bodies[b].awake; };
  auto joint = [&](const WorldForce& f) { return f.alive && gen::kForceTable[static_cast<int>(f.type)].joint; };

  // The movable bodies that a contact or a joint names, numbered as met (`ids`; `slot` gives a
  // body's number, and holds kNone for every other body, between calls too): the stage costs
  // what touches, not every body of the world. (Over all bodies, the stage took 144-291 us a
  // step for three boxes spawned into each other among 100,000 sleepers; now 3 us.)
  if (p.slot.size() < n) p.slot.resize(n, kNone);
  p.ids.clear();
  auto number = [&](uint32_t b) {
    if (movable(b) && p.slot[b] == kNone) p.slot[b] = uint32_t(p.ids.size()), p.ids.push_back(b);
  };
  for (const WorldContact& c : contacts) number(c.a), number(c.b);
  for (const WorldForce& f : forces)
    if (joint(f)) number(f.a), number(f.b);
  const uint32_t m = uint32_t(p.ids.size());
  auto at = [&](uint32_t b) { return p.slot[b]; };  // a movable body's number

  // Each movable body's contacts.
  p.first.assign(m + 1, 0);
  for (const WorldContact& c : contacts) {
    if (movable(c.a)) ++p.first[at(c.a) + 1];
    if (movable(c.b)) ++p.first[at(c.b) + 1];
  }
  for (uint32_t i = 0; i < m; ++i) p.first[i + 1] += p.first[i];
  p.adjacent.resize(p.first[m]);
  {
    std::vector<uint32_t>& fill = p.queue;
    fill.assign(p.first.begin(), p.first.end() - 1);
    for (uint32_t k = 0; k < contacts.size(); ++k) {
      if (movable(contacts[k].a)) p.adjacent[fill[at(contacts[k].a)]++] = k;
      if (movable(contacts[k].b)) p.adjacent[fill[at(contacts[k].b)]++] = k;
    }
  }
  auto other = [&](const WorldContact& c, uint32_t body) { return c.a == body ? c.b : c.a; };

  // Each body's joint partners; one jointed to what cannot move is pinned.
  p.link_first.assign(m + 1, 0);
  std::vector<uint8_t>& pinned = p.pinned;
  pinned.assign(m, 0);
  for (const WorldForce& f : forces) {
    if (!joint(f)) continue;
    const bool ma = movable(f.a), mb = movable(f.b);
    if (ma && mb) ++p.link_first[at(f.a) + 1], ++p.link_first[at(f.b) + 1];
    else if (ma) pinned[at(f.a)] = 1;
    else if (mb) pinned[at(f.b)] = 1;
  }
  for (uint32_t i = 0; i < m; ++i) p.link_first[i + 1] += p.link_first[i];
  p.linked.resize(p.link_first[m]);
  {
    std::vector<uint32_t>& fill = p.queue;
    fill.assign(p.link_first.begin(), p.link_first.end() - 1);
    for (const WorldForce& f : forces)
      if (joint(f) && movable(f.a) && movable(f.b)) p.linked[fill[at(f.a)]++] = at(f.b), p.linked[fill[at(f.b)]++] = at(f.a);
  }

  // Bodies joints join, directly or through others, move as one here, so a contact between two
  // of them (a ragdoll's leg on its other leg) cannot be pushed out: left in, it lifted the
  // whole ragdoll again each sweep, 30 cm a step while it fell at 10 m/s. The contact's spring,
  // which acts deeper there (joint_groups.h), and the joints' limits hold such an overlap.
  // A group is known by its lowest body: the jointed bodies are taken in the order of their ids.
  p.group.resize(m);
  for (uint32_t i = 0; i < m; ++i) p.group[i] = i;
  p.roots.clear();
  for (uint32_t i = 0; i < m; ++i)
    if (p.link_first[i] != p.link_first[i + 1]) p.roots.push_back(i);
  std::sort(p.roots.begin(), p.roots.end(), [&](uint32_t x, uint32_t y) { return p.ids[x] < p.ids[y]; });
  for (uint32_t i : p.roots) {
    if (p.group[i] != i) continue;
    p.queue.assign(1, i);
    for (size_t q = 0; q < p.queue.size(); ++q)
      for (uint32_t e = p.link_first[p.queue[q]]; e < p.link_first[p.queue[q] + 1]; ++e)
        if (p.group[p.linked[e]] == p.linked[e] && p.linked[e] != i) p.group[p.linked[e]] = i, p.queue.push_back(p.linked[e]);
  }
  auto group_of = [&](uint32_t b) { return p.group[at(b)]; };  // a movable body's group
  auto joined = [&](const WorldContact& c) { return movable(c.a) && movable(c.b) && group_of(c.a) == group_of(c.b); };

  // The piles that hold a deep contact: their bodies, then their levels counted from what
  // cannot move (breadth first, so each contact and body is visited a bounded number of times).
  p.level.assign(m, kFree);
  std::vector<uint8_t>& seen = p.seen;
  seen.assign(m, 0);
  p.members.clear();  // by number
  for (const WorldContact& c : contacts) {
    if (c.point.penetration <= c.hold || joined(c)) continue;
    for (uint32_t root : {c.a, c.b}) {
      if (!movable(root) || seen[at(root)]) continue;
      seen[at(root)] = 1;
      const size_t from = p.members.size();
      p.members.push_back(at(root));
      for (size_t q = from; q < p.members.size(); ++q) {
        const uint32_t i = p.members[q];
        for (uint32_t e = p.first[i]; e < p.first[i + 1]; ++e) {
          const uint32_t o = other(contacts[p.adjacent[e]], p.ids[i]);
          if (movable(o) && !seen[at(o)]) seen[at(o)] = 1, p.members.push_back(at(o));
        }
        for (uint32_t e = p.link_first[i]; e < p.link_first[i + 1]; ++e)
          if (!seen[p.linked[e]]) seen[p.linked[e]] = 1, p.members.push_back(p.linked[e]);
      }
    }
  }
  p.queue.clear();
  for (uint32_t i : p.members)
    for (uint32_t e = p.first[i]; e < p.first[i + 1]; ++e)
      if (!movable(other(contacts[p.adjacent[e]], p.ids[i]))) {
        p.level[i] = 0, p.queue.push_back(i);
        break;
      }
  for (size_t q = 0; q < p.queue.size(); ++q) {
    const uint32_t i = p.queue[q];
    for (uint32_t e = p.first[i]; e < p.first[i + 1]; ++e) {
      const uint32_t o = other(contacts[p.adjacent[e]], p.ids[i]);
      if (movable(o) && p.level[at(o)] == kFree) p.level[at(o)] = p.level[i] + 1, p.queue.push_back(at(o));
    }
  }
  auto level = [&](uint32_t b) { return movable(b) ? p.level[at(b)] : kFixed; };

  // Their contacts, lowest first: what lifts a body is met before what rests on it.
  p.order.clear();
  for (uint32_t i : p.members)
    for (uint32_t e = p.first[i]; e < p.first[i + 1]; ++e) {
      const uint32_t k = p.adjacent[e];
      const WorldContact& c = contacts[k];
      if (p.ids[i] == c.a || !movable(c.a)) p.order.push_back(k);  // once per contact
    }
  // A stable counting sort by the lower level of the two bodies: the fixed first, the free last.
  // (Levels count contacts, so there are fewer than the pile has bodies.)
  const size_t free_bucket = p.members.size() + 1;
  auto bucket = [&](uint32_t k) {
    const int32_t lowest = std::min(level(contacts[k].a), level(contacts[k].b));
    return lowest == kFree ? free_bucket : size_t(lowest + 1);
  };
  p.bucket_start.assign(free_bucket + 2, 0);
  for (uint32_t k : p.order) ++p.bucket_start[bucket(k) + 1];
  for (size_t i = 1; i < p.bucket_start.size(); ++i) p.bucket_start[i] += p.bucket_start[i - 1];
  p.queue.assign(p.order.begin(), p.order.end());
  for (uint32_t k : p.queue) p.order[p.bucket_start[bucket(k)]++] = k;

  // Each contact asks to separate by its excess over its hold, at most the step's budget; a
  // shallower one only that it gets no deeper than its hold.
  p.target.resize(p.order.size());
  for (size_t i = 0; i < p.order.size(); ++i) {
    const WorldContact& c = contacts[p.order[i]];
    p.target[i] = joined(c) ? -INFINITY : float(std::min(double(c.point.penetration) - c.hold, budget));
  }
  // Joined bodies move as one rigid group: its displacement is kept at its lowest body, its mass
  // is theirs summed, and a joint to what cannot move pins it all. (Sharing each joint's difference
  // between its two bodies instead, sweep by sweep, lifted a 1600 kg chassis on 15 kg wheels by
  // 1% of what its wheels asked a sweep: the car sank through the ground.)
  p.group_mass.assign(m, 0.0);
  for (uint32_t i : p.members) {
    p.group_mass[p.group[i]] += bodies[p.ids[i]].mass;
    if (pinned[i]) pinned[p.group[i]] = 1;  // the group's, at its lowest body
  }
  p.moved.assign(3 * size_t(m), 0.0);
  auto moved = [&](uint32_t b) { return movable(b) ? Vec3d::load(&p.moved[3 * size_t(group_of(b))]) : Vec3d{0, 0, 0}; };
  // what a push may move: not what cannot move, nor a group a joint pins to it
  auto pushable = [&](uint32_t b) { return movable(b) && !pinned[group_of(b)]; };
  auto add = [&](uint32_t b, const Vec3d& d) {
    double* x = &p.moved[3 * size_t(group_of(b))];
    x[0] += d.x, x[1] += d.y, x[2] += d.z;
  };
  const Vec3d g = Vec3d::load(s.globals.gravity);
  const Vec3d up = norm(g) > 0 ? g * (-1.0 / norm(g)) : Vec3d{0, 0, 0};
  const double tolerance = 1e-3 * s.globals.contact_hold_depth;
  auto short_by = [&](size_t i, const WorldContact& c, const Vec3d& nrm) {
    return p.target[i] - dot(moved(c.b) - moved(c.a), nrm);
  };
  // A sweep visits only the contacts whose request may have changed: those a push moved a body of
  // since their last visit, or left short. Any other would find itself met and do nothing, so
  // the result is a full sweep's, bit for bit: a pile of balls wedged in a bin, 32 sweeps of its
  // 1,100 contacts a step, does a few hundred visits a sweep once the first has been made.
  // A group that joints join moves bodies not adjacent to the contact: there every sweep is full.
  std::vector<uint8_t>& due = p.due;
  due.assign(p.order.size(), 1);
  bool track = true;
  for (uint32_t i : p.members) track = track && p.link_first[i] == p.link_first[i + 1];
  std::vector<uint32_t>& place = p.place;  // contact -> its place in the order
  if (track) {
    place.resize(contacts.size());
    for (size_t i = 0; i < p.order.size(); ++i) place[p.order[i]] = uint32_t(i);
  }
  auto moved_body = [&](uint32_t b) {
    if (!track) return;
    for (uint32_t e = p.first[at(b)]; e < p.first[at(b) + 1]; ++e) due[place[p.adjacent[e]]] = 1;
  };
  due.resize((p.order.size() + 7) / 8 * 8, 0);  // whole words of 8 places, read at once below
  for (int sweep = 0; sweep < kMaxSweeps; ++sweep) {
    double worst = 0;
    for (size_t i = 0; i < p.order.size(); ++i) {
      if (i % 8 == 0) {  // most places are not due once the first sweep is done: skip them 8 at a time
        uint64_t word;
        std::memcpy(&word, &due[i], 8);
        if (word == 0) {
          i += 7;
          continue;
        }
      }
      if (!due[i]) continue;
      due[i] = !track;
      const WorldContact& c = contacts[p.order[i]];
      const Vec3d nrm = Vec3d::load(c.point.normal);
      const double short_i = short_by(i, c, nrm);
      if (short_i <= tolerance) continue;
      double wa = pushable(c.a) ? 1.0 / p.group_mass[group_of(c.a)] : 0.0;
      double wb = pushable(c.b) ? 1.0 / p.group_mass[group_of(c.b)] : 0.0;
      const double rise = dot(nrm, up);  // b moves along n, a against it
      if (rise > kUpCosine && wb > 0) wa = 0;
      if (rise < -kUpCosine && wa > 0) wb = 0;
      if (wa + wb <= 0) continue;
      worst = std::max(worst, short_i);
      if (wa > 0) add(c.a, nrm * (-short_i * wa / (wa + wb))), moved_body(c.a);
      if (wb > 0) add(c.b, nrm * (short_i * wb / (wa + wb))), moved_body(c.b);
      if (track) due[i] = short_by(i, c, nrm) > tolerance;  // met, up to the normal's rounding
    }
    if (worst <= tolerance) break;
  }

  for (uint32_t i : p.members) {
    const uint32_t b = p.ids[i];
    const Vec3d d = moved(b);
    if (d.x == 0 && d.y == 0 && d.z == 0) continue;
    ++st.pushed_bodies;
    float* x = bodies[b].state.position;
    x[0] = float(x[0] + d.x), x[1] = float(x[1] + d.y), x[2] = float(x[2] + d.z);
  }
  // Each pair's contacts together, as collide wrote them: the order's contacts by index. A pile
  // with most of the world's contacts is listed by a scan of them, a small one sorted.
  if (p.order.size() * 16 < contacts.size()) {
    std::sort(p.order.begin(), p.order.end());
  } else {
    std::vector<uint8_t>& in = p.due;  // (its buffer, free now)
    in.assign(contacts.size(), 0);
    for (uint32_t k : p.order) in[k] = 1;
    p.order.clear();
    for (uint32_t k = 0; k < contacts.size(); ++k)
      if (in[k]) p.order.push_back(k);
  }
  for (size_t i = 0; i < p.order.size(); ++i) {
    WorldContact& c = contacts[p.order[i]];
    const Vec3d da = moved(c.a), db = moved(c.b);
    c.point.penetration = float(c.point.penetration - dot(db - da, Vec3d::load(c.point.normal)));
    const Vec3d mid = (da + db) * 0.5;  // the point sits between the surfaces
    float* x = c.point.point;
    x[0] = float(x[0] + mid.x), x[1] = float(x[1] + mid.y), x[2] = float(x[2] + mid.z);
    // A contact of a pushed pile that the push leaves a gap wider than its hold, or overlap
    // it could not reach, carries no load this step: loaded, it would drive the bodies together,
    // or throw them. A narrower gap keeps its load: a car's wheels, lifted with their chassis as
    // one until the deepest touched the hold depth, left the others a millimetre off the ground,
    // and unloaded they held the 1600 kg chassis on their own 15 kg: the car sank at 0.09 m/s.
    // A contact inside a joined group keeps its load however deep: the push cannot reach it, and
    // unloaded (tuned to a forearm's mass) it let a landing chest sink 9 cm into the forearm.
    if (!joined(c) && (c.point.penetration < -c.hold || c.point.penetration > 2 * c.hold)) c.load = 0;
    const WorldContact* before = i > 0 ? &contacts[p.order[i - 1]] : nullptr;
    if (before && before->a == c.a && before->b == c.b) continue;
    const float fa[3] = {float(da.x), float(da.y), float(da.z)}, fb[3] = {float(db.x), float(db.y), float(db.z)};
    move_anchors(bodies, memory, c.a, c.b, fa, fb);
  }
  for (uint32_t b : p.ids) p.slot[b] = kNone;
}

}  // namespace cellphys::ppe

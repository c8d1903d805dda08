#include "runtime/ppe/contact_memory.h"

#include <algorithm>
#include <cmath>
#include <iterator>

#include "runtime/base/quat.h"
#include "runtime/base/vec3.h"
#include "runtime/ppe/body_maths.h"
#include "runtime/ppe/worker_pool.h"
#include "runtime/ppe/world.h"

namespace cellphys::ppe {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr size_t kLookAhead = 16;  // a walk over pairs' memory starts this many lookups ahead

void put3(float* out, const Vec3d& v) { out[0] = float(v.x), out[1] = float(v.y), out[2] = float(v.z); }

// A point fixed in a body (or the world, which is body kWorldBody) to and from the world frame.
struct Frame {
  Vec3d x{0, 0, 0};
  Mat3d R{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
  Vec3d to_world(const float* p) const { return x + mul(R, Vec3d::load(p)); }
  void to_local(const Vec3d& w, float* out) const { put3(out, mul_transpose(R, w - x)); }
};
Frame frame_of(const std::vector<WorldBody>& bodies, uint32_t id) {
  Frame f;
  if (id == kWorldBody) return f;
  f.x = Vec3d::load(bodies[id].state.position);
  f.R = quat_to_matrix(Quatd::load(bodies[id].state.orientation));
  return f;
}

// What recall_pair needs of a body, computed once for every pair of it that one thread recalls
// near the others: its frame, its inverse inertia in the world frame and its inverse mass. A body
// is in several pairs (a box in a pile in four to six), which the recall meets close together
// (the pairs come ordered by their first body). The same operations as computed a pair at a
// time, so the same bits.
struct BodyView {
  Frame frame;
  Mat3d inverse_inertia;
  double inverse_mass;
};
class BodyViews {
 public:
  BodyViews() { std::fill(std::begin(ids_), std::end(ids_), kWorldBody); }
  const BodyView& of(const std::vector<WorldBody>& bodies, uint32_t id) {
    const size_t slot = id % kSlots;
    BodyView& v = views_[slot];
    if (ids_[slot] == id) return v;
    ids_[slot] = id;
    v.frame = frame_of(bodies, id);
    v.inverse_inertia = rotate_sym(v.frame.R, bodies[id].inverse_inertia);
    v.inverse_mass = 1.0 / bodies[id].mass;
    return v;
  }

 private:
  static constexpr size_t kSlots = 128;  // direct-mapped by id: a row of a pile's pairs and the next
  uint32_t ids_[kSlots];
  BodyView views_[kSlots];
};

bool asleep(const std::vector<WorldBody>& bodies, uint32_t id) {
  return id == kWorldBody || !bodies[id].alive || !bodies[id].awake || bodies[id].is_static;
}

}  // namespace

// Pair (a, b)'s contacts [first, end) of this step against its memory `old` (null: none):
// each contact's effective mass, strain and mode, and the pair's memory now (`now`, its
// `seen` left to the caller). Reads only the pair's own contacts and memory: pairs are
// recalled on several threads.
void recall_pair(const std::vector<WorldBody>& bodies, const WorldSettings& s, double match, BodyViews& views,
                 const ContactMemory::Pair* old, std::vector<WorldContact>& contacts, size_t first, size_t end,
                 ContactMemory::Pair& now) {
  const uint32_t a = contacts[first].a, b = contacts[first].b;
  static const BodyView kWorld{Frame{}, Mat3d{}, 0.0};
  const BodyView& va = views.of(bodies, a);
  const BodyView& vb = b == kWorldBody ? kWorld : views.of(bodies, b);
  const Frame &fa = va.frame, &fb = vb.frame;
  const Mat3d &Ia = va.inverse_inertia, &Ib = vb.inverse_inertia;
  now = ContactMemory::Pair{};
  // where the old anchors are on a now (each is compared with every point)
  Vec3d old_on_a[spu::kMaxManifoldPoints];
  for (uint32_t j = 0; old && j < old->count; ++j) old_on_a[j] = fa.to_world(old->anchors[j].on_a);
  bool used[spu::kMaxManifoldPoints] = {};
  int matched[spu::kMaxManifoldPoints];
  Vec3d strain[spu::kMaxManifoldPoints];
  Vec3d total_strain{0, 0, 0};
  double total_depth = 0, fastest_squared = 0, k_per_mass = 0, damping_per_k = 0;
  Vec3d drift{0, 0, 0};
  const size_t count = std::min(end - first, size_t(spu::kMaxManifoldPoints));
  const double inverse_ma = va.inverse_mass, inverse_mb = vb.inverse_mass;
  // Tuned by frequency and damping ratio (the default), a contact's k/m and c/k do not depend
  // on its mass: two divisions a point fewer on the way to the pair's decision.
  const double omega = 2 * kPi * s.globals.contact_hertz, ratio = s.globals.contact_damping_ratio;
  const double stiffness = s.globals.contact_stiffness, damping = s.globals.contact_damping;
  const bool tuned_k = stiffness > 0, tuned_c = damping > 0;
  const double k_per_mass_of_hertz = omega * omega, damping_per_k_of_ratio = 2 * ratio / omega;
  for (size_t i = 0; i < count; ++i) {
    WorldContact& c = contacts[first + i];
    const Vec3d p = Vec3d::load(c.point.point), n = Vec3d::load(c.point.normal);
    double w = inverse_mass_along(inverse_ma, Ia, fa.x, p, n);
    if (b != kWorldBody) w += inverse_mass_along(inverse_mb, Ib, fb.x, p, n);
    c.mass = float(1.0 / w);
    // the contact's spring and damper, as the descriptor tunes them
    double k_per_m = k_per_mass_of_hertz, cd_per_k = damping_per_k_of_ratio;
    if (tuned_k || tuned_c) {
      const double m = std::max(c.mass, c.load);
      const double k = tuned_k ? stiffness : m * omega * omega;
      const double cd = tuned_c ? damping : 2 * ratio * m * omega;
      if (tuned_k) k_per_m = k / m;
      cd_per_k = cd / k;
    }
    k_per_mass = std::max(k_per_mass, k_per_m);
    damping_per_k = std::max(damping_per_k, cd_per_k);
    // The anchor this point stuck to, if it is still near it, and how far it is strained.
    matched[i] = -1;
    double best_d = match;
    // Squared distances beyond this are surely no nearer than best_d: 1e-12 is thousands of
    // rounding errors, so the square root (correctly rounded) is taken only where it decides.
    double beyond = best_d * best_d * (1 + 1e-12);
    for (uint32_t j = 0; old && j < old->count; ++j) {
      const double d2 = squared_norm(old_on_a[j] - p);
      if (used[j] || !(d2 <= beyond)) continue;
      const double d = std::sqrt(d2);
      if (d < best_d) matched[i] = int(j), best_d = d, beyond = best_d * best_d * (1 + 1e-12);
    }
    strain[i] = {0, 0, 0};
    if (matched[i] >= 0) {
      used[matched[i]] = true;
      const ContactMemory::Anchor& an = old->anchors[matched[i]];
      strain[i] = fb.to_world(an.on_b) - old_on_a[matched[i]];
      strain[i] = strain[i] - n * dot(strain[i], n);
    }
    const Vec3d vrel = velocity_at(bodies, b, p) - velocity_at(bodies, a, p);
    const double vn = dot(vrel, n);
    const Vec3d vt = vrel - n * vn;
    fastest_squared = std::max(fastest_squared, squared_norm(vt));
    drift = drift + vt * (1.0 / double(count));
    // the tangential force, in units of depth: the anchor spring's and its damper's
    total_strain = total_strain + strain[i] + vt * cd_per_k;
    // the normal force, in units of depth, as the descriptor has it: overlapping, the
    // spring's (on at most its hold; deeper overlap is pushed out) and the damper's
    // while it closes; at a gap, the damper toward the speed that meets the surface
    const double pen = c.point.penetration, held = std::min(pen, double(c.hold));
    const double normal = pen > 0 ? held - cd_per_k * vn : (cd_per_k + s.dt) * (pen / s.dt - vn);
    total_depth += std::max(normal, 0.0);
  }
  // the fastest slip: one square root, of the largest square (a correctly rounded root keeps
  // the order, so this is the largest root, bit for bit)
  const double fastest = std::sqrt(fastest_squared);
  // Sticking or sliding, for the pair as a whole (its points share the two bodies' motion, not
  // their loads: a box on a slope presses its downhill edge harder). A sticking pair slides
  // once its tangential force leaves the friction cone (its strain and slip against mu times
  // the depth: the anchor's spring and damper against the normal ones), or once it slips
  // faster than friction stops within a step (a kick). A sliding pair sticks again once its
  // slip slows to what friction stops within a step (h mu k/m depth) and within half the
  // cone (the damper brings a slip v to rest over v c/k of strain); a slip that grows, down a
  // slope steeper than the friction angle, goes on; a slip as slow as the regularisation's (a
  // box creeping on a slope it should hold) sticks. A sliding pair whose slip turned back since
  // the last step sticks too: friction alone never reverses a slip, so its constant force
  // overshot one that it stopped within the step. (Judged by the normal's effective mass, a
  // sphere's slip, which friction turns through 2/7 of that mass, reversed every step: a
  // ragdoll's head held against the ground by its neck rocked at 4 cm/s for ever.)
  const double mu = contacts[first].friction, depth = total_depth / double(count);
  const bool stoppable = fastest <= s.dt * mu * k_per_mass * depth && fastest * damping_per_k <= 0.5 * mu * depth;
  bool sliding;
  if (!old) sliding = !stoppable;
  else if (old->sliding && dot(drift, Vec3d::load(old->drift)) < 0) sliding = false;
  else if (old->sliding) sliding = !(stoppable && (fastest <= old->slip || fastest <= s.globals.slip_velocity));
  else sliding = norm(total_strain) > mu * total_depth || !stoppable;
  now.sliding = sliding;
  now.slip = float(fastest);
  put3(now.drift, drift);
  for (size_t i = 0; i < count; ++i) {
    WorldContact& c = contacts[first + i];
    ContactMemory::Anchor& an = now.anchors[now.count++];
    if (sliding || matched[i] < 0) {  // anchored afresh where it is
      strain[i] = {0, 0, 0};
      fa.to_local(Vec3d::load(c.point.point), an.on_a);
      fb.to_local(Vec3d::load(c.point.point), an.on_b);
    } else {
      an = old->anchors[matched[i]];
    }
    c.sticking = sliding ? 0.0f : 1.0f;
    if (matched[i] >= 0 && (old->held_gaps >> matched[i] & 1u)) c.fall = 0.0f;
    put3(c.anchor, strain[i]);
  }
}

void recall_contacts(const std::vector<WorldBody>& bodies, const WorldSettings& s, const std::vector<uint32_t>& woken,
                     bool all, WorkerPool* pool, ContactMemory& memory, std::vector<WorldContact>& contacts) {
  // The pairs this recall may forget: the last one's, and the sleepers' of bodies that woke.
  std::vector<uint64_t>& review = memory.review;
  review.clear();
  if (all) {
    memory.dormant.clear();
    for (const auto& kv : memory.pairs) review.push_back(kv.first);
  } else {
    review.swap(memory.active);
    memory.dormant.take(woken, review);
  }
  memory.active.clear();
  // An anchor is the same one while this step's point is this close to where it stuck.
  const double match = std::max(2.0 * s.globals.contact_slop, 1e-3);
  // Each pair's contacts against its memory, on the threads (the map is only read), then the
  // memory written in pair order: the entries found first (no entry moves), then the new ones.
  std::vector<ContactMemory::Span>& spans = memory.spans;
  spans.clear();
  for (size_t first = 0, end; first < contacts.size(); first = end) {
    for (end = first; end < contacts.size() && contacts[end].a == contacts[first].a && contacts[end].b == contacts[first].b; ++end) {
    }
    spans.push_back({first, end, nullptr, {}});
  }
  for (size_t i = 0; i < spans.size(); ++i) {
    if (i + kLookAhead < spans.size()) memory.pairs.prefetch(pair_key(contacts[spans[i + kLookAhead].first].a, contacts[spans[i + kLookAhead].first].b));
    spans[i].found = memory.pairs.find(pair_key(contacts[spans[i].first].a, contacts[spans[i].first].b));
  }
  auto recall_span = [&](size_t i, BodyViews& views) {
    ContactMemory::Span& sp = spans[i];
    recall_pair(bodies, s, match, views, sp.found, contacts, sp.first, sp.end, sp.now);
    sp.now.seen = memory.step + 1;
  };
  constexpr size_t kPairsPerTask = 64;
  if (pool && pool->size() > 1 && spans.size() >= 4 * kPairsPerTask) {
    pool->for_each((spans.size() + kPairsPerTask - 1) / kPairsPerTask, [&](size_t task, int) {
      BodyViews views;
      for (size_t i = task * kPairsPerTask; i < std::min(spans.size(), (task + 1) * kPairsPerTask); ++i) recall_span(i, views);
    });
  } else {
    BodyViews views;
    for (size_t i = 0; i < spans.size(); ++i) recall_span(i, views);
  }
  for (const ContactMemory::Span& sp : spans)
    if (sp.found) *sp.found = sp.now;
  for (const ContactMemory::Span& sp : spans) {
    const uint64_t key = pair_key(contacts[sp.first].a, contacts[sp.first].b);
    if (!sp.found) memory.pairs.emplace(key, sp.now);
    memory.active.push_back(key);
  }
  // Pairs not touching this step are forgotten, but for sleepers' (they are not collided),
  // which wait aside until a body of theirs wakes. Decided from the world alone, so a world
  // restored from a snapshot forgets the same ones.
  ++memory.step;
  std::vector<uint64_t>& resting = memory.resting;
  resting.clear();
  for (size_t i = 0; i < review.size(); ++i) {
    if (i + kLookAhead < review.size()) memory.pairs.prefetch(review[i + kLookAhead]);
    const uint64_t key = review[i];
    const ContactMemory::Pair* pair = memory.pairs.find(key);
    if (!pair || pair->seen == memory.step) continue;
    const uint32_t a = uint32_t(key >> 32), b = uint32_t(key);
    if (a < bodies.size() && bodies[a].alive && asleep(bodies, a) && asleep(bodies, b)) resting.push_back(key);
    else memory.pairs.erase(key);
  }
  memory.dormant.add(resting);
}

void note_held_gaps(const std::vector<WorldBody>& bodies, const WorldSettings& s,
                    const std::vector<WorldContact>& contacts, ContactMemory& memory) {
  std::vector<std::pair<uint64_t, uint32_t>>& pairs_held = memory.held;
  pairs_held.clear();
  for (size_t first = 0, end; first < contacts.size(); first = end) {
    const uint32_t a = contacts[first].a, b = contacts[first].b;
    for (end = first; end < contacts.size() && contacts[end].a == a && contacts[end].b == b; ++end) {
    }
    uint32_t held = 0;
    const size_t count = std::min(end - first, size_t(spu::kMaxManifoldPoints));
    for (size_t i = 0; i < count; ++i) {
      const WorldContact& c = contacts[first + i];
      if (c.point.penetration >= 0) continue;
      const Vec3d p = Vec3d::load(c.point.point), n = Vec3d::load(c.point.normal);
      const double vn = dot(velocity_at(bodies, b, p) - velocity_at(bodies, a, p), n);
      // held: resting on something else, neither closing within the step nor approaching
      // faster than a resting contact settles (a body falling from afar is not held)
      if (vn > c.point.penetration / s.dt && vn > -s.globals.contact_rest_speed) held |= 1u << i;
    }
    pairs_held.emplace_back(pair_key(a, b), held);
  }
  for (size_t i = 0; i < pairs_held.size(); ++i) {
    if (i + kLookAhead < pairs_held.size()) memory.pairs.prefetch(pairs_held[i + kLookAhead].first);
    if (ContactMemory::Pair* found = memory.pairs.find(pairs_held[i].first)) found->held_gaps = pairs_held[i].second;
  }
}

void move_anchors(const std::vector<WorldBody>& bodies, ContactMemory& memory, uint32_t a, uint32_t b,
                  const float da[3], const float db[3]) {
  ContactMemory::Pair* found = memory.pairs.find(pair_key(a, b));
  if (!found) return;
  const Vec3d mid = (Vec3d::load(da) + Vec3d::load(db)) * 0.5;
  const Mat3d Ra = frame_of(bodies, a).R, Rb = frame_of(bodies, b).R;
  const Vec3d on_a = mul_transpose(Ra, mid - Vec3d::load(da)), on_b = mul_transpose(Rb, mid - Vec3d::load(db));
  ContactMemory::Pair& pair = *found;
  for (uint32_t j = 0; j < pair.count; ++j) {
    put3(pair.anchors[j].on_a, Vec3d::load(pair.anchors[j].on_a) + on_a);
    put3(pair.anchors[j].on_b, Vec3d::load(pair.anchors[j].on_b) + on_b);
  }
}

void forget_body(ContactMemory& memory, uint32_t id) {
  memory.pairs.erase_if([id](uint64_t key, const ContactMemory::Pair&) { return uint32_t(key >> 32) == id || uint32_t(key) == id; });
  std::vector<uint64_t> gone;  // (the active list's keys of it are found missing by the next recall)
  memory.dormant.take({id}, gone);
}

}  // namespace cellphys::ppe

#include "runtime/ppe/contact_memory.h"

#include <algorithm>
#include <cmath>

#include "runtime/base/quat.h"
#include "runtime/base/vec3.h"
#include "runtime/ppe/world.h"

namespace cellphys::ppe {

namespace {

constexpr double kPi = 3.14159265358979323846;
double squared(double x) { return x * x; }

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

// 1 / (the velocity change along n at the point per unit impulse along n) of one body.
double inverse_mass_along(const WorldBody& b, const Frame& f, const Vec3d& p, const Vec3d& n) {
  const Vec3d rn = cross(p - f.x, n);
  return 1.0 / b.mass + dot(rn, mul(rotate_sym(f.R, b.inverse_inertia), rn));
}

Vec3d velocity_at(const std::vector<WorldBody>& bodies, uint32_t id, const Vec3d& p) {
  if (id == kWorldBody) return {0, 0, 0};
  const BodyState& s = bodies[id].state;
  return Vec3d::load(s.velocity) + cross(Vec3d::load(s.angular_velocity), p - Vec3d::load(s.position));
}

bool asleep(const std::vector<WorldBody>& bodies, uint32_t id) {
  return id == kWorldBody || !bodies[id].alive || !bodies[id].awake || bodies[id].is_static;
}

}  // namespace

void recall_contacts(const std::vector<WorldBody>& bodies, const WorldSettings& s, ContactMemory& memory,
                     std::vector<WorldContact>& contacts) {
  // An anchor is the same one while this step's point is this close to where it stuck.
  const double match = std::max(2.0 * s.globals.contact_slop, 1e-3);
  ContactMemory next;
  for (const auto& [key, pair] : memory.pairs) {  // sleepers' contacts are not collided
    const uint32_t a = uint32_t(key >> 32), b = uint32_t(key);
    if (a < bodies.size() && bodies[a].alive && asleep(bodies, a) && asleep(bodies, b)) next.pairs.emplace(key, pair);
  }
  for (size_t first = 0, end; first < contacts.size(); first = end) {
    const uint32_t a = contacts[first].a, b = contacts[first].b;
    for (end = first; end < contacts.size() && contacts[end].a == a && contacts[end].b == b; ++end) {
    }
    const auto old_it = memory.pairs.find(pair_key(a, b));
    const ContactMemory::Pair* old = old_it == memory.pairs.end() ? nullptr : &old_it->second;
    const Frame fa = frame_of(bodies, a), fb = frame_of(bodies, b);
    ContactMemory::Pair now;
    bool used[spu::kMaxManifoldPoints] = {};
    for (size_t i = first; i < end && now.count < spu::kMaxManifoldPoints; ++i) {
      WorldContact& c = contacts[i];
      const Vec3d p = Vec3d::load(c.point.point), n = Vec3d::load(c.point.normal);
      double w = inverse_mass_along(bodies[a], fa, p, n);
      if (b != kWorldBody) w += inverse_mass_along(bodies[b], fb, p, n);
      c.mass = float(1.0 / w);
      // The anchor this point stuck to, if it is still near it.
      int best = -1;
      double best_d = match;
      for (uint32_t k = 0; old && k < old->count; ++k) {
        const double d = norm(fa.to_world(old->anchors[k].on_a) - p);
        if (!used[k] && d < best_d) best = int(k), best_d = d;
      }
      // Sticking or sliding. A sticking point slides once its strain leaves the friction cone
      // (mu times the depth: the tangential spring's force against the normal one's). A sliding
      // point sticks again once its slip slows, to what friction stops within a step (h mu
      // k/m depth); a slip that grows, down a slope steeper than the friction angle, goes on.
      Vec3d vt = velocity_at(bodies, b, p) - velocity_at(bodies, a, p);
      vt = vt - n * dot(vt, n);
      const double slip = norm(vt), depth = std::max(double(c.point.penetration), 0.0);
      const double k_per_mass = s.globals.contact_stiffness > 0 ? s.globals.contact_stiffness / std::max(c.mass, c.load)
                                                                  : squared(2 * kPi * s.globals.contact_hertz);
      const bool stoppable = slip <= s.dt * c.friction * k_per_mass * depth;
      ContactMemory::Anchor& an = now.anchors[now.count++];
      Vec3d strain{0, 0, 0};
      bool sliding;
      if (best >= 0) {
        used[best] = true;
        an = old->anchors[best];
        strain = fb.to_world(an.on_b) - fa.to_world(an.on_a);
        strain = strain - n * dot(strain, n);
        sliding = an.sliding ? !(stoppable && slip <= an.slip) : norm(strain) > c.friction * depth;
      } else {
        sliding = !stoppable;
      }
      if (sliding || best < 0) {  // a sliding point is anchored afresh where it is
        strain = {0, 0, 0};
        fa.to_local(p, an.on_a);
        fb.to_local(p, an.on_b);
      }
      an.slip = float(slip);
      an.sliding = sliding;
      c.sticking = sliding ? 0.0f : 1.0f;
      put3(c.anchor, strain);
    }
    next.pairs[pair_key(a, b)] = now;
  }
  memory = std::move(next);
}

void forget_body(ContactMemory& memory, uint32_t id) {
  for (auto it = memory.pairs.begin(); it != memory.pairs.end();)
    if (uint32_t(it->first >> 32) == id || uint32_t(it->first) == id) it = memory.pairs.erase(it);
    else ++it;
}

}  // namespace cellphys::ppe

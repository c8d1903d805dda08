#include "runtime/ppe/snapshot_checks.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

#include "cellphys/gen/force_table.h"
#include "runtime/ppe/world.h"

namespace cellphys::ppe {

namespace {

// The same tolerance as World::add_body's warning: a quaternion the World keeps is unit to
// about 1e-7 (the kernel normalises it every step).
constexpr double kUnitTolerance = 1e-4;

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

[[noreturn]] void refuse(const std::string& who, const std::string& why) { throw WorldError("snapshot: " + who + ": " + why); }

void finite(const std::string& who, const char* field, const float* p, int n) {
  for (int k = 0; k < n; ++k)
    if (!std::isfinite(p[k])) {
      const std::string name = n == 1 ? field : std::string(field) + "[" + std::to_string(k) + "]";
      refuse(who, name + " is not finite (" + num(p[k]) + ")");
    }
}

void at_least_zero(const std::string& who, const char* field, float v) {
  finite(who, field, &v, 1);
  if (!(v >= 0.0f)) refuse(who, std::string(field) + " is negative (" + num(v) + ")");
}

void unit(const std::string& who, const char* field, const float* p, int n) {
  finite(who, field, p, n);
  double s = 0;
  for (int k = 0; k < n; ++k) s += double(p[k]) * p[k];
  const double norm = std::sqrt(s);
  if (!(std::fabs(norm - 1.0) <= kUnitTolerance))
    refuse(who, std::string(field) + " is not a unit " + (n == 4 ? "quaternion" : "vector") + " (norm " + num(norm) + ")");
}

bool zero(const float* p, int n) {
  for (int k = 0; k < n; ++k)
    if (p[k] != 0.0f) return false;
  return true;
}

std::string body_who(uint32_t i) { return "body " + std::to_string(i); }

// A body a record may name: one the snapshot has (alive or removed), or the world when allowed.
void refers(const std::vector<WorldBody>& bodies, const std::string& who, const char* field, uint32_t id, bool world_ok) {
  if (id == kWorldBody && world_ok) return;
  if (id >= bodies.size())
    refuse(who, std::string(field) + " is body " + std::to_string(id) + ", which does not exist (" +
                    std::to_string(bodies.size()) + " bodies)");
}

}  // namespace

void check_snapshot_body(const ShapeDictionary& shapes, const WorldBody& b, uint32_t i) {
  const std::string who = body_who(i);
  if (b.shape >= shapes.size())
    refuse(who, "shape " + std::to_string(b.shape) + " does not exist (" + std::to_string(shapes.size()) + " shapes)");
  finite(who, "scale", &b.scale, 1);
  if (!(b.scale > 0.0f)) refuse(who, "scale is not positive (" + num(b.scale) + ")");
  finite(who, "position", b.state.position, 3);
  unit(who, "orientation", b.state.orientation, 4);
  finite(who, "velocity", b.state.velocity, 3);
  finite(who, "angular velocity", b.state.angular_velocity, 3);
  at_least_zero(who, "friction", b.friction);
  at_least_zero(who, "linear damping", b.linear_damping);
  at_least_zero(who, "angular damping", b.angular_damping);
  at_least_zero(who, "sleep timer", b.sleep_timer);
  finite(who, "mass", &b.mass, 1);
  finite(who, "inertia", b.inertia, 6);
  finite(who, "inverse inertia", b.inverse_inertia, 6);
  if (b.is_static) {
    if (!zero(b.state.velocity, 3) || !zero(b.state.angular_velocity, 3)) refuse(who, "a static body is moving");
    if (b.mass != 0.0f || !zero(b.inertia, 6) || !zero(b.inverse_inertia, 6)) refuse(who, "a static body has a mass or inertia");
    if (b.sleep_group != -1) refuse(who, "a static body is in a sleeping group");
    return;
  }
  if (!(b.mass > 0.0f)) refuse(who, "mass is not positive (" + num(b.mass) + ")");
  for (int k = 0; k < 3; ++k)
    if (!(b.inertia[k] > 0.0f))
      refuse(who, "inertia[" + std::to_string(k) + "] (a principal moment) is not positive (" + num(b.inertia[k]) + ")");
  float inverse[6];
  if (!invert_inertia(b.inertia, inverse)) refuse(who, "inertia is not invertible");
  if (std::memcmp(inverse, b.inverse_inertia, sizeof inverse) != 0) refuse(who, "inverse inertia is not the inverse of its inertia");
}

void check_snapshot_force(const std::vector<WorldBody>& bodies, const WorldForce& f, uint32_t i) {
  const gen::ForceInfo& info = gen::kForceTable[static_cast<int>(f.type)];
  const std::string who = "force " + std::to_string(i) + " (" + info.name + ")";
  if (info.kind == gen::ForceKind::global) refuse(who, "a global force cannot be an instance");
  refers(bodies, who, "body a", f.a, false);
  refers(bodies, who, "body b", f.b, true);
  for (uint32_t k = 0; k < info.num_params; ++k) {
    const gen::ParamInfo& p = info.params[k];
    float v[3];
    std::memcpy(v, f.instance.data() + p.offset, 4 * p.lanes);
    finite(who, p.name, v, static_cast<int>(p.lanes));
    for (uint32_t l = 0; l < p.lanes; ++l)
      if (!p.admits(v[l])) refuse(who, std::string(p.name) + " must be " + p.min_relation() + " " + num(p.min) + ", is " + num(v[l]));
  }
  if (!f.alive) return;  // a removed force's bodies may be gone
  const WorldBody& a = bodies[f.a];
  if (!a.alive) refuse(who, "body a (" + body_who(f.a) + ") was removed");
  if (a.is_static) refuse(who, "body a (" + body_who(f.a) + ") is static");
  if (f.b == kWorldBody) {
    if (info.kind == gen::ForceKind::binary && !info.world_anchor) refuse(who, "it cannot be anchored to the world");
    return;
  }
  if (info.kind == gen::ForceKind::unary) refuse(who, "it acts on one body, but body b is " + body_who(f.b));
  const WorldBody& b = bodies[f.b];
  if (f.b == f.a) refuse(who, "body a and body b are the same body");
  if (!b.alive) refuse(who, "body b (" + body_who(f.b) + ") was removed");
  if (b.is_static) refuse(who, "body b (" + body_who(f.b) + ") is static");
}

void check_snapshot_contact(const std::vector<WorldBody>& bodies, const WorldContact& c, uint32_t g, uint32_t k) {
  const std::string who = "sleeping group " + std::to_string(g) + ", contact " + std::to_string(k);
  refers(bodies, who, "body a", c.a, false);
  refers(bodies, who, "body b", c.b, true);
  finite(who, "point", c.point.point, 3);
  unit(who, "normal", c.point.normal, 3);
  finite(who, "penetration", &c.point.penetration, 1);
  at_least_zero(who, "friction", c.friction);
  at_least_zero(who, "mass", c.mass);
  at_least_zero(who, "load", c.load);
  finite(who, "anchor", c.anchor, 3);
  at_least_zero(who, "sticking", c.sticking);
  if (c.sticking > 1.0f) refuse(who, "sticking is over 1 (" + num(c.sticking) + ")");
  finite(who, "hold", &c.hold, 1);
  if (!(c.hold > 0.0f)) refuse(who, "hold is not above 0 (" + num(c.hold) + ")");
  finite(who, "fall", &c.fall, 1);
  if (c.fall > 0.0f) refuse(who, "fall is above 0 (" + num(c.fall) + ")");
}

void check_snapshot_pair(const std::vector<WorldBody>& bodies, uint64_t key, const ContactMemory::Pair& p) {
  const uint32_t a = uint32_t(key >> 32), b = uint32_t(key);
  const std::string who = "contact memory of bodies " + std::to_string(a) + " and " +
                          (b == kWorldBody ? std::string("the world") : std::to_string(b));
  refers(bodies, who, "body a", a, false);
  refers(bodies, who, "body b", b, true);
  if (p.count > static_cast<uint32_t>(spu::kMaxManifoldPoints))
    refuse(who, std::to_string(p.count) + " anchors, more than a manifold's " + std::to_string(spu::kMaxManifoldPoints));
  if (p.sliding > 1) refuse(who, "sliding is " + std::to_string(p.sliding) + ", not 0 or 1");
  at_least_zero(who, "slip", p.slip);
  finite(who, "drift", p.drift, 3);
  if (p.held_gaps >> p.count)
    refuse(who, "held gaps " + std::to_string(p.held_gaps) + " name a point past its " + std::to_string(p.count));
  for (uint32_t k = 0; k < p.count; ++k) {
    finite(who, "anchor on a", p.anchors[k].on_a, 3);
    finite(who, "anchor on b", p.anchors[k].on_b, 3);
  }
}

void check_snapshot_event_pairs(const std::vector<WorldBody>& bodies, const std::vector<uint64_t>& keys, bool sensors,
                                const char* what) {
  for (size_t k = 0; k < keys.size(); ++k) {
    const uint32_t a = uint32_t(keys[k] >> 32), b = uint32_t(keys[k]);
    const std::string who = std::string(what) + " " + std::to_string(k) + " (bodies " + std::to_string(a) + " and " +
                            std::to_string(b) + ")";
    refers(bodies, who, "the first body", a, false);
    refers(bodies, who, "the second body", b, false);
    if (!bodies[a].alive || !bodies[b].alive) refuse(who, "names a removed body");
    if (k > 0 && keys[k] <= keys[k - 1]) refuse(who, "out of order or listed twice");
    if (sensors ? !bodies[a].sensor || bodies[b].sensor : a >= b || bodies[a].sensor || bodies[b].sensor)
      refuse(who, sensors ? "is not a sensor and a body that is not one" : "is not two bodies that are not sensors, the lower id first");
  }
}

void check_snapshot_sleeping(const std::vector<WorldBody>& bodies, const SleepingGroups& s) {
  const size_t ng = s.groups.size();
  std::vector<uint32_t> members(ng, 0);  // bodies naming each group
  for (uint32_t i = 0; i < bodies.size(); ++i) {
    const int32_t g = bodies[i].sleep_group;
    if (g < -1 || g >= static_cast<int32_t>(ng))
      refuse(body_who(i), "sleeping group " + std::to_string(g) + " does not exist (" + std::to_string(ng) + " groups)");
    if (g >= 0) ++members[static_cast<size_t>(g)];
  }
  for (uint32_t g = 0; g < ng; ++g) {
    const std::string who = "sleeping group " + std::to_string(g);
    const std::vector<uint32_t>& list = s.groups[g].bodies;
    for (uint32_t id : list) {
      refers(bodies, who, "a member", id, false);
      const WorldBody& b = bodies[id];
      if (!b.alive || b.is_static || b.awake)
        refuse(who, "member " + body_who(id) + " is " + (!b.alive ? "removed" : b.is_static ? "static" : "awake"));
      if (b.sleep_group != static_cast<int32_t>(g))
        refuse(who, "member " + body_who(id) + " names sleeping group " + std::to_string(b.sleep_group));
    }
    // every member names g, so more listed than naming it means one listed twice
    if (list.size() != members[g])
      refuse(who, std::to_string(list.size()) + " members listed, " + std::to_string(members[g]) + " bodies in it");
    if (list.empty() && !s.groups[g].contacts.empty()) refuse(who, "an empty group keeps contacts");
  }
  std::vector<char> freed(ng, 0);
  for (int32_t g : s.free) {
    if (g < 0 || static_cast<size_t>(g) >= ng)
      refuse("free slot", "sleeping group " + std::to_string(g) + " does not exist (" + std::to_string(ng) + " groups)");
    const std::string who = "sleeping group " + std::to_string(g);
    if (freed[static_cast<size_t>(g)]) refuse(who, "freed twice");
    freed[static_cast<size_t>(g)] = 1;
    if (!s.groups[static_cast<size_t>(g)].bodies.empty()) refuse(who, "freed, but it has members");
  }
}

}  // namespace cellphys::ppe

#include "runtime/spu/overlap_push.h"

#include <algorithm>

#include "runtime/base/vec3.h"

namespace cellphys::spu {

using namespace cellphys::gen;

namespace {

// Sweeps over the contacts, each taking its part of the step's push.
constexpr int kSweeps = 2;
constexpr float kUnreached = 1e9f;

Vec3d moved(const float* scratch, int32_t body) {
  return body < 0 ? Vec3d{0, 0, 0} : Vec3d::load(scratch + 4 * body);
}
void add(float* scratch, int32_t body, const Vec3d& d) {
  float* p = scratch + 4 * body;
  p[0] += float(d.x), p[1] += float(d.y), p[2] += float(d.z);
}

}  // namespace

void push_out_overlaps(const IslandView& v, float h, float* scratch) {
  const Island_Params& g = *v.params;
  const float step_budget = g.contact_push_speed * h;
  Contact_Force* contacts = nullptr;
  uint32_t count = 0;
  for (int s = 0; s < v.num_sections(); ++s)
    if (v.sections[s].force_type == static_cast<uint32_t>(ForceType::contact))
      contacts = v.instances<Contact_Force>(v.sections[s]), count = v.sections[s].count;
  if (!contacts || step_budget <= 0) return;
  bool any = false;
  for (uint32_t c = 0; c < count && !any; ++c) any = contacts[c].penetration > g.contact_hold_depth;
  if (!any) return;
  // Per body: its displacement (xyz) and its level (w): contacts away from what cannot move
  // (the world, a ghost of another part). A contact moves its upper body only, so the
  // ground lifts a column level by level instead of pressing its lowest box into itself.
  const int n = v.num_bodies();
  for (int i = 0; i < n; ++i) {
    float* p = scratch + 4 * i;
    p[0] = p[1] = p[2] = 0.0f;
    p[3] = v.bodies[i].inverse_mass > 0 ? kUnreached : -1.0f;
  }
  auto level = [&](int32_t b) { return b < 0 ? -1.0f : scratch[4 * b + 3]; };
  float top = -1.0f;
  for (bool changed = true; changed;) {
    changed = false;
    for (uint32_t c = 0; c < count; ++c) {
      const int32_t a = contacts[c].body_a, b = contacts[c].body_b;
      const float la = level(a), lb = level(b);
      if (la > lb + 1) scratch[4 * a + 3] = lb + 1, changed = true, top = std::max(top, lb + 1);
      if (b >= 0 && lb > la + 1) scratch[4 * b + 3] = la + 1, changed = true, top = std::max(top, la + 1);
    }
  }
  auto inverse_mass = [&](int32_t b) { return b < 0 ? 0.0f : v.bodies[b].inverse_mass; };
  const double per_sweep = step_budget / kSweeps;
  // The contacts whose lower body is at level `at`, lower levels first.
  auto push_level = [&](float at) {
    for (uint32_t c = 0; c < count; ++c) {
      const Contact_Force& k = contacts[c];
      const float la = level(k.body_a), lb = level(k.body_b);
      if (std::min(la, lb) != at) continue;
      double wa = inverse_mass(k.body_a), wb = inverse_mass(k.body_b);
      if (la < lb) wa = 0;
      if (lb < la) wb = 0;
      if (wa + wb <= 0) continue;
      const Vec3d nrm = Vec3d::load(k.normal);
      const double depth = k.penetration - dot(moved(scratch, k.body_b) - moved(scratch, k.body_a), nrm);
      const double push = std::min(depth - g.contact_hold_depth, per_sweep);
      if (push <= 0) continue;
      if (wa > 0) add(scratch, k.body_a, nrm * (-push * wa / (wa + wb)));
      if (wb > 0) add(scratch, k.body_b, nrm * (push * wb / (wa + wb)));
    }
  };
  for (int sweep = 0; sweep < kSweeps; ++sweep) {
    for (float at = -1.0f; at <= top; at += 1.0f) push_level(at);
    push_level(kUnreached);  // bodies touching nothing that cannot move: shared by inverse mass
  }
  for (int i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) v.bodies[i].position[a] += scratch[4 * i + a];
  for (uint32_t c = 0; c < count; ++c) {
    Contact_Force& k = contacts[c];
    const Vec3d da = moved(scratch, k.body_a), db = moved(scratch, k.body_b);
    k.penetration -= float(dot(db - da, Vec3d::load(k.normal)));
    const Vec3d mid = (da + db) * 0.5;  // the point sits between the surfaces
    k.point[0] += float(mid.x), k.point[1] += float(mid.y), k.point[2] += float(mid.z);
  }
}

}  // namespace cellphys::spu

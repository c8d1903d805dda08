#include "runtime/ppe/step_collide.h"

#include <algorithm>
#include <cmath>

#include "cellphys/gen/force_table.h"
#include "runtime/base/vec3.h"
#include "runtime/ppe/contact_loads.h"
#include "runtime/ppe/world.h"
#include "runtime/spu/narrow_phase.h"

namespace cellphys::ppe {

namespace {

// Speculative reach: how far a body can close on another within the step (its speed, and
// the spin of its farthest point, times dt). Boxes grow by it plus half the slop, so a pair
// is found when its gap may close to within the slop: fast bodies meet contacts before they
// tunnel, resting ones carry none that cannot act.
float reach_in_step(const WorldBody& b, const Aabb& box, const WorldSettings& s) {
  if (b.is_static) return 0.0f;
  const Vec3d half = (Vec3d::load(box.max) - Vec3d::load(box.min)) * 0.5;
  const double speed = norm(Vec3d::load(b.state.velocity)), spin = norm(Vec3d::load(b.state.angular_velocity));
  return static_cast<float>(s.dt * (speed + spin * norm(half)) + s.contact_margin);
}

// Boxes of every live non-plane body, grown by its reach; the region cull decides its kind.
void broad_phase(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                 CollideScratch& c, StepStats& st) {
  const uint32_t n = static_cast<uint32_t>(bodies.size());
  c.boxes.resize(n);
  c.reach.assign(n, 0.0f);
  c.kinds.assign(n, BoxKind::none);
  c.planes.clear();
  for (uint32_t i = 0; i < n; ++i) {
    const WorldBody& b = bodies[i];
    if (!b.alive) continue;
    if (shapes.type(b.shape) == spu::ShapeType::plane) {
      c.planes.push_back(i);
      continue;
    }
    Aabb& box = c.boxes[i];
    shapes.world_aabb(b.shape, pose_of(b), box.min, box.max);
    c.reach[i] = reach_in_step(b, box, s);
    const float grow = c.reach[i] + 0.5f * s.globals.contact_slop;
    for (int k = 0; k < 3; ++k) box.min[k] -= grow, box.max[k] += grow;
    if (!inside_region(box, s.region_min, s.region_max)) {
      if (!b.is_static) ++st.outside_region;
      continue;
    }
    c.kinds[i] = b.is_static ? BoxKind::fixed : b.awake ? BoxKind::awake : BoxKind::asleep;
    ++st.broad_phase_boxes;
  }
}

// Every awake body whose grown box reaches within half the slop of a plane.
void plane_pairs(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                 CollideScratch& c) {
  const uint32_t n = static_cast<uint32_t>(bodies.size());
  for (uint32_t p : c.planes) {
    const spu::ShapeView& pv = shapes.view(bodies[p].shape);
    for (uint32_t i = 0; i < n; ++i) {
      if (c.kinds[i] != BoxKind::awake) continue;
      const Aabb& B = c.boxes[i];
      double lowest = 0;  // the (grown) box corner furthest along -normal
      for (int k = 0; k < 3; ++k) lowest += pv.normal[k] * double(pv.normal[k] >= 0 ? B.min[k] : B.max[k]);
      if (lowest - pv.offset <= 0.5 * s.globals.contact_slop) c.pairs.emplace_back(std::min(i, p), std::max(i, p));
    }
  }
}

uint64_t pair_key(uint32_t i, uint32_t j) { return uint64_t(std::min(i, j)) << 32 | std::max(i, j); }

// The body pairs the joints join, sorted, and the sweep's pairs without them.
void drop_joined_pairs(const std::vector<WorldForce>& forces, CollideScratch& c) {
  c.joined.clear();
  for (const WorldForce& f : forces)
    if (f.alive && f.b != kWorldBody && gen::kForceTable[static_cast<int>(f.type)].joint) c.joined.push_back(pair_key(f.a, f.b));
  if (c.joined.empty()) return;
  std::sort(c.joined.begin(), c.joined.end());
  c.pairs.erase(std::remove_if(c.pairs.begin(), c.pairs.end(),
                               [&](const std::pair<uint32_t, uint32_t>& p) {
                                 return std::binary_search(c.joined.begin(), c.joined.end(), pair_key(p.first, p.second));
                               }),
                c.pairs.end());
}

void narrow_phase(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                  CollideScratch& c, std::vector<WorldContact>& contacts, StepStats& st) {
  contacts.clear();
  c.touched.clear();
  c.sensed.clear();
  for (const auto& [i, j] : c.pairs) {
    uint32_t a = i, b = j;
    const bool sensing = bodies[a].sensor || bodies[b].sensor;
    if (sensing && bodies[a].sensor == bodies[b].sensor) continue;  // sensors do not sense sensors
    if (sensing ? bodies[a].sensor : bodies[a].is_static) std::swap(a, b);
    spu::ContactPoint cp[spu::kMaxManifoldPoints];
    const float margin = sensing ? 0.0f : s.globals.contact_slop + c.reach[a] + c.reach[b];
    const int k = spu::collide(shapes.view(bodies[a].shape), pose_of(bodies[a]), shapes.view(bodies[b].shape),
                               pose_of(bodies[b]), margin, cp);
    if (sensing) {  // a is the visitor, b the sensor: inside while a point overlaps
      if (std::any_of(cp, cp + k, [](const spu::ContactPoint& p) { return p.penetration > 0.0f; })) c.sensed.emplace_back(b, a);
      continue;
    }
    if (k > 0) ++st.narrow_phase_pairs;
    if (k > 0) c.touched.push_back({a, b, uint32_t(contacts.size()), uint32_t(k)});
    const float mu = std::sqrt(bodies[a].friction * bodies[b].friction);
    for (int p = 0; p < k; ++p) contacts.push_back({a, bodies[b].is_static ? kWorldBody : b, cp[p], mu, 0.0f, 0.0f, {}, 1.0f});
  }
}

}  // namespace

void collide(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces, const ShapeDictionary& shapes,
             const WorldSettings& settings, CollideScratch& scratch, ContactMemory& memory,
             std::vector<WorldContact>& contacts, StepStats& st) {
  {
    StageTimer t(st.times.broad_ms);
    broad_phase(bodies, shapes, settings, scratch, st);
  }
  {
    StageTimer t(st.times.mid_ms);
    scratch.sap.find_pairs(scratch.boxes, scratch.kinds, scratch.pairs);
    plane_pairs(bodies, shapes, settings, scratch);
    std::sort(scratch.pairs.begin(), scratch.pairs.end());
    drop_joined_pairs(forces, scratch);
    st.mid_phase_pairs = static_cast<uint32_t>(scratch.pairs.size());
  }
  StageTimer t(st.times.narrow_ms);
  narrow_phase(bodies, shapes, settings, scratch, contacts, st);
  carry_loads(bodies, forces, settings, contacts, scratch.loads);
  recall_contacts(bodies, settings, memory, contacts);
}

}  // namespace cellphys::ppe

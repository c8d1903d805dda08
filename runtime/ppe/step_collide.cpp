#include "runtime/ppe/step_collide.h"

#include <algorithm>
#include <cmath>

#include "cellphys/gen/force_table.h"
#include "runtime/base/radix_sort.h"
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

// A body's grown box, its reach, and whether the region holds it.
bool grown_box(const WorldBody& b, const ShapeDictionary& shapes, const WorldSettings& s, Aabb& box, float& reach) {
  shapes.world_aabb(b.shape, pose_of(b), box.min, box.max);
  reach = reach_in_step(b, box, s);
  const float grow = reach + 0.5f * s.globals.contact_slop;
  for (int k = 0; k < 3; ++k) box.min[k] -= grow, box.max[k] += grow;
  return inside_region(box, s.region_min, s.region_max);
}

// Files body i again after a change: a sleeping or static body's box into the tree of still
// boxes, a plane into the list of planes; an awake body's box is made each step.
void refile(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s, uint32_t i,
            CollideScratch& c) {
  if (c.leaf[i] >= 0) c.still.remove(c.leaf[i]), c.leaf[i] = -1;
  if (c.outside[i]) c.outside[i] = 0, --c.still_outside;
  c.kinds[i] = BoxKind::none;
  c.reach[i] = 0.0f;
  const auto plane = std::lower_bound(c.planes.begin(), c.planes.end(), i);
  const bool listed = plane != c.planes.end() && *plane == i;
  const WorldBody& b = bodies[i];
  const bool is_plane = b.alive && shapes.type(b.shape) == spu::ShapeType::plane;
  if (is_plane != listed) {
    if (is_plane) c.planes.insert(plane, i);
    else c.planes.erase(plane);
  }
  if (!b.alive || is_plane || (b.awake && !b.is_static)) return;
  if (!grown_box(b, shapes, s, c.boxes[i], c.reach[i])) {
    if (!b.is_static) c.outside[i] = 1, ++c.still_outside;
    return;
  }
  c.kinds[i] = b.is_static ? BoxKind::fixed : BoxKind::asleep;
  c.leaf[i] = c.still.insert(i, c.boxes[i]);
}

// Awake bodies a task of the broad phase makes boxes for at a time, and the fewest handed to
// the threads: at 30,000 bodies they halve the stage; at 1,000 the gain is within the noise,
// but 512 puts world1000 on 2 workers (and so the ThreadSanitizer pass) on this path.
constexpr size_t kBoxesPerTask = 256, kParallelBoxes = 512;

// The awake bodies' boxes made afresh, each in its own slot: on the threads when there are many.
// Returns how many fell outside the region.
size_t make_awake_boxes(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                        const std::vector<uint32_t>& awake, WorkerPool* pool, CollideScratch& c) {
  auto make = [&](size_t begin, size_t end) {
    size_t outside = 0;
    for (size_t k = begin; k < end; ++k) {
      const uint32_t i = awake[k];
      const bool in = grown_box(bodies[i], shapes, s, c.boxes[i], c.reach[i]);
      c.kinds[i] = in ? BoxKind::awake : BoxKind::none;
      outside += !in;
    }
    return outside;
  };
  const size_t n = awake.size();
  if (!pool || pool->size() < 2 || n < kParallelBoxes) return make(0, n);
  c.outside_of_task.assign((n + kBoxesPerTask - 1) / kBoxesPerTask, 0);
  pool->for_ranges(n, kBoxesPerTask, [&](size_t begin, size_t end, int) {
    c.outside_of_task[begin / kBoxesPerTask] = make(begin, end);
  });
  size_t outside = 0;
  for (size_t o : c.outside_of_task) outside += o;
  return outside;
}

// The boxes: the still ones kept, those of bodies that changed filed again, the awake ones
// made afresh (grown by their reach), each culled against the region.
void broad_phase(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                 const BodyChanges& changes, WorkerPool* pool, CollideScratch& c, StepStats& st) {
  const uint32_t n = static_cast<uint32_t>(bodies.size());
  if (changes.all) {
    c.still.clear();
    c.leaf.assign(n, -1);
    c.outside.assign(n, 0);
    c.still_outside = 0;
    c.boxes.resize(n);
    c.reach.assign(n, 0.0f);
    c.kinds.assign(n, BoxKind::none);
    c.planes.clear();
    for (uint32_t i = 0; i < n; ++i) refile(bodies, shapes, s, i, c);
  } else {
    c.leaf.resize(n, -1);
    c.outside.resize(n, 0);
    c.boxes.resize(n);
    c.reach.resize(n, 0.0f);
    c.kinds.resize(n, BoxKind::none);
    for (uint32_t i : changes.changed) refile(bodies, shapes, s, i, c);
  }
  st.outside_region += c.still_outside;
  st.broad_phase_boxes += c.still.size();
  const size_t outside = make_awake_boxes(bodies, shapes, s, changes.awake, pool, c);
  st.outside_region += static_cast<uint32_t>(outside);
  st.broad_phase_boxes += static_cast<uint32_t>(changes.awake.size() - outside);
}

// Every awake body's box against the others' (the sweep) and against the still ones (the tree).
void box_pairs(const BodyChanges& changes, CollideScratch& c) {
  c.pairs.clear();
  c.sap.find_pairs(c.boxes, c.kinds, changes.awake, c.pairs);
  for (uint32_t i : changes.awake)
    if (c.kinds[i] == BoxKind::awake)
      c.still.overlap(c.boxes[i], [&](uint32_t j) { c.pairs.emplace_back(std::min(i, j), std::max(i, j)); });
}

// Every awake body whose grown box reaches within half the slop of a plane.
void plane_pairs(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                 const BodyChanges& changes, CollideScratch& c) {
  for (uint32_t p : c.planes) {
    const spu::ShapeView& pv = shapes.view(bodies[p].shape);
    for (uint32_t i : changes.awake) {
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

void find_manifold(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                   const CollideScratch& c, std::pair<uint32_t, uint32_t> pair, PairManifold& m) {
  m.a = pair.first, m.b = pair.second;
  m.sensing = bodies[m.a].sensor || bodies[m.b].sensor;
  m.k = -1;
  if (m.sensing && bodies[m.a].sensor == bodies[m.b].sensor) return;  // sensors do not sense sensors
  if (m.sensing ? bodies[m.a].sensor : bodies[m.a].is_static) std::swap(m.a, m.b);
  const float margin = m.sensing ? 0.0f : s.globals.contact_slop + c.reach[m.a] + c.reach[m.b];
  m.k = spu::collide(shapes.view(bodies[m.a].shape), pose_of(bodies[m.a]), shapes.view(bodies[m.b].shape),
                     pose_of(bodies[m.b]), margin, m.cp);
}

// Pairs a task of the parallel narrow phase takes at a time, and the fewest pairs worth the threads.
constexpr size_t kPairsPerTask = 32, kParallelPairs = 256;

void narrow_phase(const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes, const WorldSettings& s,
                  WorkerPool* pool, CollideScratch& c, std::vector<WorldContact>& contacts, StepStats& st) {
  contacts.clear();
  c.touched.clear();
  c.sensed.clear();
  // The manifolds are found in any order (on several threads), and taken in pair order.
  auto take = [&](const PairManifold& m) {
    if (m.k < 0) return;
    if (m.sensing) {  // a is the visitor, b the sensor: inside while a point overlaps
      if (std::any_of(m.cp, m.cp + m.k, [](const spu::ContactPoint& p) { return p.penetration > 0.0f; }))
        c.sensed.emplace_back(m.b, m.a);
      return;
    }
    if (m.k > 0) ++st.narrow_phase_pairs;
    if (m.k > 0) c.touched.push_back({m.a, m.b, uint32_t(contacts.size()), uint32_t(m.k)});
    const float mu = std::sqrt(bodies[m.a].friction * bodies[m.b].friction);
    // Written in place: a contact built on the stack and copied was read back wider than it was
    // written, and waited for its stores (a tenth of the narrow stage of 1,040 boxes on the ground).
    const uint32_t b = bodies[m.b].is_static ? kWorldBody : m.b;
    for (int p = 0; p < m.k; ++p) {
      WorldContact& wc = contacts.emplace_back();
      wc.a = m.a, wc.b = b, wc.point = m.cp[p], wc.friction = mu;
    }
  };
  const size_t n = c.pairs.size();
  if (!pool || pool->size() < 2 || n < kParallelPairs) {
    PairManifold m;
    for (const auto& pair : c.pairs) find_manifold(bodies, shapes, s, c, pair, m), take(m);
    return;
  }
  c.manifolds.resize(n);
  pool->for_each((n + kPairsPerTask - 1) / kPairsPerTask, [&](size_t task, int) {
    for (size_t p = task * kPairsPerTask; p < std::min(n, (task + 1) * kPairsPerTask); ++p)
      find_manifold(bodies, shapes, s, c, c.pairs[p], c.manifolds[p]);
  });
  for (const PairManifold& m : c.manifolds) take(m);
}

}  // namespace

void collide(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces, const ShapeDictionary& shapes,
             const WorldSettings& settings, const BodyChanges& changes, WorkerPool* pool, CollideScratch& scratch,
             ContactMemory& memory, std::vector<WorldContact>& contacts, StepStats& st) {
  {
    StageTimer t(st, &StageTimes::broad_ms);
    broad_phase(bodies, shapes, settings, changes, pool, scratch, st);
  }
  {
    StageTimer t(st, &StageTimes::mid_ms);
    box_pairs(changes, scratch);
    plane_pairs(bodies, shapes, settings, changes, scratch);
    radix_sort_pairs(scratch.pairs, scratch.sorting);
    drop_joined_pairs(forces, scratch);
    st.mid_phase_pairs = static_cast<uint32_t>(scratch.pairs.size());
  }
  StageTimer t(st, &StageTimes::narrow_ms);
  narrow_phase(bodies, shapes, settings, pool, scratch, contacts, st);
  scratch.groups.build(bodies, forces);
  set_contact_hold_and_fall(settings, scratch.groups, contacts);
  carry_loads(bodies, forces, settings, contacts, scratch.loads);
  load_joined_contacts(bodies, scratch.groups, contacts);
  scratch.woken.clear();
  for (uint32_t i : changes.changed)
    if (bodies[i].alive && !bodies[i].is_static && bodies[i].awake) scratch.woken.push_back(i);
  std::sort(scratch.woken.begin(), scratch.woken.end());
  scratch.woken.erase(std::unique(scratch.woken.begin(), scratch.woken.end()), scratch.woken.end());
  recall_contacts(bodies, settings, scratch.woken, changes.all, pool, memory, contacts);
}

}  // namespace cellphys::ppe

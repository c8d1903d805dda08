#include "runtime/ppe/contact_loads.h"

#include <algorithm>
#include <cmath>

#include "cellphys/gen/force_table.h"
#include "runtime/base/vec3.h"
#include "runtime/ppe/world.h"

namespace cellphys::ppe {

namespace {

constexpr double kPi = 3.14159265358979323846;
// A contact holds its upper body up if its normal is within about 84 degrees of vertical:
// walls do not carry what leans on them.
constexpr double kSupportCosine = 0.1;
// A body moving along gravity slower than this many steps of free fall would give it rests on
// what its joints hold it to; a faster one is falling on them.
constexpr double kRestingSteps = 6.0;

}  // namespace

void carry_loads(const std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces, const WorldSettings& s,
                 std::vector<WorldContact>& contacts, LoadScratch& sc) {
  for (WorldContact& c : contacts) c.load = 0.0f;
  const Vec3d g = Vec3d::load(s.globals.gravity);
  const double gn = norm(g);
  if (gn <= 0 || contacts.empty()) return;
  const Vec3d down = g * (1.0 / gn);
  const size_t n = bodies.size();
  if (sc.named.size() < n) {
    sc.named.resize(n, 0);
    sc.support.resize(n, 0.0);
    sc.held.resize(n, 0);
    sc.below.resize(n, 0);
    sc.linked.resize(n, 0);
    sc.weight.resize(n, 0.0);
    sc.first_of.resize(n, 0);
    sc.count.resize(n, 0);
  }
  sc.involved.clear();
  const auto name = [&](uint32_t id) {
    if (id != kWorldBody && !sc.named[id]) sc.named[id] = 1, sc.involved.push_back(id);
  };
  for (const WorldContact& c : contacts) name(c.a), name(c.b);
  for (const WorldForce& f : forces)
    if (f.alive && gen::kForceTable[static_cast<int>(f.type)].joint) name(f.a), name(f.b);
  std::vector<int64_t>& upper = sc.upper;
  std::vector<double>& share = sc.share;
  std::vector<double>& support = sc.support;
  upper.assign(contacts.size(), -1);
  share.assign(contacts.size(), 0.0);
  for (size_t i = 0; i < contacts.size(); ++i) {
    const WorldContact& c = contacts[i];
    // A gap wider than the slop holds nothing up yet: it is a body on its way, which a loaded
    // contact would drive to the surface as if the weight above pressed on it.
    if (c.point.penetration < -s.globals.contact_slop) continue;
    const double along = dot(Vec3d::load(c.point.normal), down);  // n from a to b
    if (std::fabs(along) < kSupportCosine) continue;
    // gravity presses b into a when n points up from a (along < 0): b rests on a
    const uint32_t top = along < 0 ? c.b : c.a;
    if (top == kWorldBody || bodies[top].is_static) continue;
    const uint32_t low = top == c.a ? c.b : c.a;
    if (low != kWorldBody && !bodies[low].is_static) sc.linked[top] = 1, sc.linked[low] = 1;
    upper[i] = top;
    share[i] = std::fabs(along);
    support[top] += share[i];
  }
  // A body hands its weight down its joints too: a car's chassis to its wheels, a raised arm to
  // the shoulder. Each joint to a dynamic body below it takes a share, as a contact straight
  // under it would; a joint to the world or a static body holds it all. Without this a wheel's
  // contact was tuned to the wheel alone, and a 1600 kg car sank through the ground at 0.3 m/s;
  // with joints taking a share only from a body no contact held up, a ragdoll's chest lying on
  // its own forearm left its upper arm's ground contact tuned to the arm, which sank past its
  // hold every step, the push stage lifting the ragdoll back: it never slept.
  auto height = [&](uint32_t i) { return -dot(Vec3d::load(bodies[i].state.position), down); };
  std::vector<std::pair<uint32_t, uint32_t>>& joints = sc.joints;
  std::vector<uint8_t>& held = sc.held;
  joints.clear();
  for (const WorldForce& f : forces) {
    if (!f.alive || !gen::kForceTable[static_cast<int>(f.type)].joint) continue;
    const bool fixed_a = bodies[f.a].is_static, fixed_b = f.b == kWorldBody || bodies[f.b].is_static;
    if (fixed_a || fixed_b) {
      if (!fixed_a) held[f.a] = 1;
      if (!fixed_b) held[f.b] = 1;
      continue;
    }
    if (height(f.a) >= height(f.b)) joints.emplace_back(f.a, f.b);
    else joints.emplace_back(f.b, f.a);
  }
  std::sort(joints.begin(), joints.end());
  // Only a body that rests on its joints, not one falling on them: a ragdoll falling feet first
  // handed its whole weight to the foot that touched, whose contact, tuned to it, threw the
  // foot and opened its joints by 70 cm. Resting is slower along gravity than a few steps of fall.
  // A body that contacts hold up hands weight only to a joint whose lower body something holds
  // up in turn (the ground under a ragdoll's arm), not along a chain hanging free: a welded
  // frame falling through the air, its arm resting on its other arm.
  const double falling = kRestingSteps * gn * s.dt;
  auto carries = [&](const std::pair<uint32_t, uint32_t>& j) {
    return !held[j.first] && std::fabs(dot(Vec3d::load(bodies[j.first].state.velocity), down)) <= falling &&
           (support[j.first] <= 0 || support[j.second] > 0 || held[j.second]);
  };
  std::vector<uint32_t>& below = sc.below;
  for (const auto& j : joints)
    if (carries(j)) ++below[j.first], sc.linked[j.second] = 1;
  // Top to bottom: a body's weight, with what rests on it, splits over its supports. A body
  // resting on static ground alone, with nothing dynamic on it, carries its own weight only:
  // it goes first, in any order, unsorted (most bodies of a scattered world).
  // (std::sort with the index as the tie-break: the order of a stable sort, with no buffer;
  // each body's height found once, not at each comparison: a third of the sort's time)
  std::vector<uint32_t>& order = sc.order;
  std::vector<std::pair<double, uint32_t>>& ranked = sc.ranked;
  order.clear();
  ranked.clear();
  for (uint32_t i : sc.involved)
    if (support[i] > 0 || below[i] > 0) {
      if (below[i] == 0 && !sc.linked[i]) order.push_back(i);
      else ranked.emplace_back(height(i), i);
    }
  std::sort(ranked.begin(), ranked.end(), [](const std::pair<double, uint32_t>& x, const std::pair<double, uint32_t>& y) {
    return x.first != y.first ? x.first > y.first : x.second < y.second;
  });
  for (const auto& r : ranked) order.push_back(r.second);
  std::vector<double>& weight = sc.weight;
  // The contacts grouped by the body they hold up, in contact order within a body (a counting
  // sort): by_upper[first_of[i] .. first_of[i] + count[i]) hold body i up.
  std::vector<size_t>& first_of = sc.first_of;
  std::vector<uint32_t>& count = sc.count;
  for (size_t i = 0; i < contacts.size(); ++i)
    if (upper[i] >= 0) ++count[size_t(upper[i])];
  size_t entries = 0;
  for (uint32_t b : sc.involved) first_of[b] = entries, entries += count[b], count[b] = 0;
  std::vector<size_t>& by_upper = sc.by_upper;
  by_upper.resize(entries);
  for (size_t i = 0; i < contacts.size(); ++i)
    if (upper[i] >= 0) by_upper[first_of[size_t(upper[i])] + count[size_t(upper[i])]++] = i;
  const double omega = 2 * kPi * s.globals.contact_hertz;
  const double to_load = gn / (omega * omega * s.contact_load_depth);  // weight (kg) -> load mass
  for (uint32_t top : order) {
    weight[top] += bodies[top].mass;
    const double supports = support[top] + below[top];
    if (below[top] > 0) {
      const auto from = std::lower_bound(joints.begin(), joints.end(), std::make_pair(top, uint32_t(0)));
      for (auto j = from; j != joints.end() && j->first == top; ++j)
        if (carries(*j)) weight[j->second] += weight[top] / supports;
    }
    for (size_t k = first_of[top]; k < first_of[top] + count[top]; ++k) {
      const size_t i = by_upper[k];
      const double carried = weight[top] * share[i] / supports;
      WorldContact& c = contacts[i];
      c.load = float(carried * to_load);
      const uint32_t below = c.a == top ? c.b : c.a;
      if (below != kWorldBody && !bodies[below].is_static) weight[below] += carried;
    }
  }
  for (uint32_t b : sc.involved)
    sc.named[b] = 0, support[b] = 0, held[b] = 0, sc.below[b] = 0, sc.linked[b] = 0, weight[b] = 0, count[b] = 0;
}

float gravity_fall(const float n[3], bool against_static, const WorldSettings& s) {
  const double along = dot(Vec3d::load(s.globals.gravity), Vec3d::load(n));  // b's fall away from a
  return float(s.dt * (against_static ? std::min(-along, 0.0) : -std::fabs(along)));
}

}  // namespace cellphys::ppe

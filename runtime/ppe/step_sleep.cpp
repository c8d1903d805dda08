#include "runtime/ppe/step_sleep.h"

#include <algorithm>

#include "runtime/base/vec3.h"
#include "runtime/ppe/world.h"

namespace cellphys::ppe {

void wake_body(std::vector<WorldBody>& bodies, SleepingGroups& sleeping, uint32_t id) {
  WorldBody& b = bodies[id];
  b.sleep_timer = 0.0f;
  if (b.awake || b.is_static) return;
  const int32_t g = b.sleep_group;
  if (g < 0) {
    b.awake = true;
    sleeping.changed.push_back(id);
    return;
  }
  for (uint32_t m : sleeping.groups[g].bodies) {
    sleeping.changed.push_back(m);
    bodies[m].awake = true;
    bodies[m].sleep_group = -1;
    bodies[m].sleep_timer = 0.0f;
  }
  sleeping.groups[g] = SleepGroup{};
  sleeping.free.push_back(g);
}

void wake_touched_groups(std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces,
                         std::vector<WorldContact>& contacts, SleepingGroups& sleeping, StepStats& st) {
  StageTimer t(st, &StageTimes::wake_ms);
  for (bool changed = true; changed;) {
    changed = false;
    auto touch = [&](uint32_t x, uint32_t y) {
      if (y == kWorldBody) return;
      const WorldBody &bx = bodies[x], &by = bodies[y];
      if (bx.awake == by.awake || bx.is_static || by.is_static) return;
      const uint32_t sleeper = bx.awake ? y : x;
      const int32_t g = bodies[sleeper].sleep_group;
      if (g >= 0) {
        const std::vector<WorldContact>& kept = sleeping.groups[g].contacts;
        contacts.insert(contacts.end(), kept.begin(), kept.end());
      }
      wake_body(bodies, sleeping, sleeper);
      ++st.woken;
      changed = true;
    };
    for (size_t c = 0; c < contacts.size(); ++c) touch(contacts[c].a, contacts[c].b);
    for (const WorldForce& f : forces)
      if (f.alive) touch(f.a, f.b);
  }
}

void sleep_quiet_islands(const WorldSettings& s, const std::vector<IslandContent>& islands,
                         const std::vector<uint8_t>& failed,
                         const std::vector<WorldContact>& contacts, std::vector<WorldBody>& bodies,
                         SleepingGroups& sleeping, StepStats& st) {
  StageTimer t(st, &StageTimes::sleep_ms);
  if (!s.sleeping) return;
  const float lin2 = s.sleep_linear * s.sleep_linear, ang2 = s.sleep_angular * s.sleep_angular;
  for (size_t k = 0; k < islands.size(); ++k) {
    const IslandContent& isl = islands[k];
    bool all = true;
    for (uint32_t i : isl.bodies) {
      WorldBody& b = bodies[i];
      const float v2 = squared_norm(Vec3f::load(b.state.velocity)), a2 = squared_norm(Vec3f::load(b.state.angular_velocity));
      // an island whose step failed is not at rest, however still it was kept
      b.sleep_timer = (v2 < lin2 && a2 < ang2 && !failed[k]) ? b.sleep_timer + s.dt : 0.0f;
      all = all && b.sleep_timer >= s.sleep_time;
    }
    if (!all || isl.bodies.empty()) continue;
    int32_t g;
    if (!sleeping.free.empty()) g = sleeping.free.back(), sleeping.free.pop_back();
    else g = static_cast<int32_t>(sleeping.groups.size()), sleeping.groups.emplace_back();
    SleepGroup& grp = sleeping.groups[g];
    grp.bodies = isl.bodies;
    for (uint32_t c : isl.contacts) grp.contacts.push_back(contacts[c]);
    for (uint32_t i : isl.bodies) {
      WorldBody& b = bodies[i];
      b.awake = false;
      b.sleep_group = g;
      sleeping.changed.push_back(i);
      std::fill(b.state.velocity, b.state.velocity + 3, 0.0f);
      std::fill(b.state.angular_velocity, b.state.angular_velocity + 3, 0.0f);
    }
    st.fell_asleep += static_cast<uint32_t>(isl.bodies.size());
  }
}

}  // namespace cellphys::ppe

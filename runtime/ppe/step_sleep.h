// Sleeping: stage 2 of the step wakes the sleeping groups that awake bodies or forces touch,
// stage 7 puts islands that have been quiet for the sleep time to sleep as one group. A
// sleeping group keeps its contacts, unchanged while every member sleeps, and gives them back
// when it wakes.
#pragma once
#include <cstdint>
#include <vector>

#include "runtime/ppe/body_records.h"
#include "runtime/ppe/island_packer.h"
#include "runtime/ppe/step_stats.h"

namespace cellphys::ppe {

struct WorldSettings;

/// The sleeping groups and the free slots among them, and the ids of the bodies whose set may
/// have changed since the step last looked (woke, fell asleep; the world adds those added,
/// removed, or moved while static), or that all may have.
struct SleepingGroups {
  std::vector<SleepGroup> groups;
  std::vector<int32_t> free;
  std::vector<uint32_t> changed;
  bool all_changed = true;
};

/// Wakes body `id` (resets its sleep timer) and, when it sleeps in a group, the whole group,
/// whose slot is freed. Static bodies never sleep or wake.
void wake_body(std::vector<WorldBody>& bodies, SleepingGroups& sleeping, uint32_t id);

/// Stage 2: a sleeping body in contact with an awake one, or joined to one by a force, wakes
/// its group, whose contacts are appended to `contacts`; repeated until nothing changes.
void wake_touched_groups(std::vector<WorldBody>& bodies, const std::vector<WorldForce>& forces,
                         std::vector<WorldContact>& contacts, SleepingGroups& sleeping, StepStats& st);

/// Stage 7: advances every island body's sleep timer; an island whose bodies have all been
/// slower than the sleep thresholds for the sleep time goes to sleep as one group, with its
/// contacts and its velocities zeroed. An island whose step failed (`failed`, per island)
/// restarts its timers: it is never left to sleep in the state that failed.
void sleep_quiet_islands(const WorldSettings& s, const std::vector<IslandContent>& islands,
                         const std::vector<uint8_t>& failed, const std::vector<WorldContact>& contacts, std::vector<WorldBody>& bodies,
                         SleepingGroups& sleeping, StepStats& st);

}  // namespace cellphys::ppe

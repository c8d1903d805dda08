// The events CSV of `cellphys run --events`: a header, then one row per contact or sensor event
// of each step (docs/events.md),
// step,t,event,a,b,px,py,pz,nx,ny,nz,approach_speed,impulse
// event is touch_begin, touch_end, sensor_begin or sensor_end; a sensor's row names the sensor
// as a and the visitor as b and leaves the numbers empty, as does a touch_end.
#pragma once
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "runtime/ppe/world.h"

namespace cellphys::cli {

class EventsCsv {
 public:
  /// `bodies` and `ids` as the trajectory's: each body's CSV name (a body not listed is named by
  /// its number).
  EventsCsv(const std::vector<ppe::BodyId>& bodies, const std::vector<std::string>& ids);
  void write_header(FILE* f) const;
  /// The last step's events, a row each.
  void write_step(FILE* f, const ppe::World& world, uint64_t step, double t) const;

 private:
  std::string name(ppe::BodyId id) const;
  std::vector<std::string> names_;  // by body id
};

}  // namespace cellphys::cli

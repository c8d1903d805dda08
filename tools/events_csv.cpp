#include "tools/events_csv.h"

#include "tools/trajectory_csv.h"

namespace cellphys::cli {

EventsCsv::EventsCsv(const std::vector<ppe::BodyId>& bodies, const std::vector<std::string>& ids) {
  for (size_t i = 0; i < bodies.size() && i < ids.size(); ++i) {
    if (bodies[i] >= names_.size()) names_.resize(bodies[i] + 1);
    names_[bodies[i]] = ids[i];
  }
}

std::string EventsCsv::name(ppe::BodyId id) const {
  return id < names_.size() && !names_[id].empty() ? names_[id] : std::to_string(id);
}

void EventsCsv::write_header(FILE* f) const {
  std::fputs("step,t,event,a,b,px,py,pz,nx,ny,nz,approach_speed,impulse\n", f);
}

void EventsCsv::write_step(FILE* f, const ppe::World& world, uint64_t step, double t) const {
  char head[64];
  const int n = std::snprintf(head, sizeof head, "%llu,%.9g,", static_cast<unsigned long long>(step), t);
  std::string line;
  for (const ppe::ContactEvent& e : world.contact_events()) {
    const bool begin = e.kind == ppe::ContactEvent::Kind::begin;
    line.assign(head, static_cast<size_t>(n));
    line += begin ? "touch_begin," : "touch_end,";
    line += name(e.a) + ',' + name(e.b);
    if (begin) {
      for (float v : e.point) line += ',', put_float(line, v);
      for (float v : e.normal) line += ',', put_float(line, v);
      line += ',', put_float(line, e.approach_speed);
      line += ',', put_float(line, e.impulse);
    } else {
      line += ",,,,,,,,";
    }
    line += '\n';
    std::fwrite(line.data(), 1, line.size(), f);
  }
  for (const ppe::SensorEvent& e : world.sensor_events()) {
    line.assign(head, static_cast<size_t>(n));
    line += e.kind == ppe::SensorEvent::Kind::begin ? "sensor_begin," : "sensor_end,";
    line += name(e.sensor) + ',' + name(e.visitor) + ",,,,,,,,\n";
    std::fwrite(line.data(), 1, line.size(), f);
  }
}

}  // namespace cellphys::cli

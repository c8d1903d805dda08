#include "tools/trajectory_csv.h"

#include <charconv>

namespace cellphys::cli {

void put_float(std::string& line, float v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  line.append(buf, r.ptr);
}

std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\r\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

void write_trajectory_header(FILE* f) { std::fputs("step,t,body,px,py,pz,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz\n", f); }

void write_trajectory_rows(FILE* f, const ppe::World& world, const std::vector<ppe::BodyId>& bodies, uint64_t step,
                           double t, const std::vector<std::string>& ids) {
  std::string line;
  line.reserve(256);
  char head[64];
  const int n = std::snprintf(head, sizeof head, "%llu,%.9g,", static_cast<unsigned long long>(step), t);
  for (size_t i = 0; i < bodies.size(); ++i) {
    const ppe::BodyState s = world.state(bodies[i]);
    line.assign(head, static_cast<size_t>(n));
    line += ids[i];
    for (float v : s.position) line += ',', put_float(line, v);
    for (float v : s.orientation) line += ',', put_float(line, v);
    for (float v : s.velocity) line += ',', put_float(line, v);
    for (float v : s.angular_velocity) line += ',', put_float(line, v);
    line += '\n';
    std::fwrite(line.data(), 1, line.size(), f);
  }
}

}  // namespace cellphys::cli

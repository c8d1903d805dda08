#include "runtime/ppe/world_checks.h"

#include <cmath>
#include <cstring>

namespace cellphys::ppe {

using namespace cellphys::gen;

namespace {

bool finite(const float* p, int n) {
  for (int i = 0; i < n; ++i)
    if (!std::isfinite(p[i])) return false;
  return true;
}

double quaternion_norm(const float q[4]) {
  return std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
}

}  // namespace

void check_body_desc(const ShapeDictionary& shapes, const BodyDesc& d, bool is_static, const std::string& who) {
  if (d.shape >= shapes.size()) throw WorldError(who + ": shape " + std::to_string(d.shape) + " does not exist");
  if (!(d.scale > 0.0f) || !std::isfinite(d.scale)) throw WorldError(who + ": scale must be positive and finite");
  if (!finite(d.state.position, 3) || !finite(d.state.orientation, 4) || !finite(d.state.velocity, 3) || !finite(d.state.angular_velocity, 3))
    throw WorldError(who + ": position, orientation and velocities must be finite");
  if (!(d.friction >= 0.0f) || !std::isfinite(d.friction)) throw WorldError(who + ": friction must be >= 0");
  if (!(d.linear_damping >= 0.0f) || !(d.angular_damping >= 0.0f) || !std::isfinite(d.linear_damping) ||
      !std::isfinite(d.angular_damping))
    throw WorldError(who + ": damping must be >= 0");
  if (quaternion_norm(d.state.orientation) < 1e-6) throw WorldError(who + ": orientation is a zero quaternion");
  if (is_static) return;
  if (!(d.mass > 0.0f && std::isfinite(d.mass))) {
    if (d.mass != 0.0f) throw WorldError(who + ": mass must be positive and finite");
    if (!(d.density > 0.0f) || !std::isfinite(d.density)) throw WorldError(who + ": a dynamic body needs a positive mass or density");
  }
  if (d.has_inertia && (!finite(d.inertia, 6) || !(d.inertia[0] > 0) || !(d.inertia[1] > 0) || !(d.inertia[2] > 0)))
    throw WorldError(who + ": inertia needs positive, finite principal moments");
}

void check_body_state(const BodyState& s, const std::string& who) {
  if (!finite(s.position, 3) || !finite(s.orientation, 4) || !finite(s.velocity, 3) || !finite(s.angular_velocity, 3))
    throw WorldError(who + ": state must be finite");
  if (quaternion_norm(s.orientation) < 1e-6) throw WorldError(who + ": orientation is a zero quaternion");
}

void check_impulse(const float impulse[3], const float point[3], const std::string& who) {
  if (!finite(impulse, 3) || !finite(point, 3)) throw WorldError(who + ": impulse and point must be finite");
}

void normalise_orientation(const float q[4], float out[4], const std::string& who, std::vector<std::string>& warnings) {
  const double qn = quaternion_norm(q);
  for (int k = 0; k < 4; ++k) out[k] = static_cast<float>(q[k] / qn);
  if (std::fabs(qn - 1.0) > 1e-4) warnings.push_back(who + ": orientation was not a unit quaternion; normalised");
}

const ForceInfo& force_type_info(const std::string& type) {
  for (const ForceInfo& f : kForceTable)
    if (type == f.name) {
      if (f.kind == ForceKind::global) throw WorldError("force " + type + " is global: it is set in the world settings");
      return f;
    }
  std::string known;
  for (const ForceInfo& f : kForceTable) known += (known.empty() ? "" : ", ") + std::string(f.name);
  throw WorldError("unknown force type '" + type + "' (known: " + known + ")");
}

void set_force_params(const ForceInfo& info, const ForceParams& params, std::vector<unsigned char>& instance) {
  const std::string type = info.name;
  for (const auto& [name, values] : params) {
    const ParamInfo* p = nullptr;
    for (uint32_t k = 0; k < info.num_params; ++k)
      if (name == info.params[k].name) p = &info.params[k];
    if (!p) throw WorldError("force " + type + ": unknown parameter '" + name + "'");
    if (values.size() != p->lanes)
      throw WorldError("force " + type + ": parameter '" + name + "' takes " + std::to_string(p->lanes) + " number(s)");
    if (!finite(values.data(), static_cast<int>(values.size())))
      throw WorldError("force " + type + ": parameter '" + name + "' is not finite");
    for (float v : values)
      if (!p->admits(v))
        throw WorldError("force " + type + ": parameter '" + name + "' must be " + p->min_relation() + " " + std::to_string(p->min));
    std::memcpy(instance.data() + p->offset, values.data(), 4 * values.size());
  }
}

}  // namespace cellphys::ppe

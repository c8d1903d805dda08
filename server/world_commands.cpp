#include "server/world_commands.h"

#include <cmath>
#include <string>

namespace cellphys::server {

namespace {

using protocol::Type;

constexpr double kPi = 3.14159265358979323846;
constexpr double kDragHertz = 2.0;  // a default drag's spring: the body follows the target at about 2 Hz

CommandError invalid(const char* type, const std::string& field, const std::string& reason) {
  return CommandError{protocol::ErrorCode::invalid, std::string(type) + "." + field, reason};
}

std::string num(double v, int digits = 9) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

// The first non-finite component of v, named `field[k]`.
std::optional<CommandError> finite(const char* type, const char* field, const float* v, int n) {
  for (int k = 0; k < n; ++k)
    if (!std::isfinite(v[k])) return invalid(type, std::string(field) + "[" + std::to_string(k) + "]", "not a finite number");
  return std::nullopt;
}

double length(const float* v) { return std::sqrt(double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]); }

std::optional<CommandError> in_region(const char* type, const char* field, const float* p, const ppe::WorldSettings& s) {
  if (auto e = finite(type, field, p, 3)) return e;
  for (int k = 0; k < 3; ++k)
    if (p[k] < s.region_min[k] || p[k] > s.region_max[k])
      return invalid(type, std::string(field) + "[" + std::to_string(k) + "]",
                     num(p[k]) + " is outside the world's region (" + num(s.region_min[k]) + " to " +
                         num(s.region_max[k]) + ")");
  return std::nullopt;
}

// A dynamic body that exists, or why not.
std::optional<CommandError> dynamic_body(const char* type, uint32_t id, const ppe::World& w) {
  if (!w.has_body(id)) return invalid(type, "body", "no body " + std::to_string(id) + " in this world");
  if (w.is_static(id)) return invalid(type, "body", "body " + std::to_string(id) + " is static");
  return std::nullopt;
}

std::optional<CommandError> positive(const char* type, const char* field, float v, double max) {
  if (!std::isfinite(v)) return invalid(type, field, "not a finite number");
  if (!(v > 0)) return invalid(type, field, num(v) + " is not > 0");
  if (v > max) return invalid(type, field, num(v) + " is more than " + num(max));
  return std::nullopt;
}

// The world point p in the frame of a body at (x, q): R^T (p - x).
void to_body(const ppe::BodyState& s, const float p[3], float out[3]) {
  const double w = s.orientation[0], x = s.orientation[1], y = s.orientation[2], z = s.orientation[3];
  const double r[3] = {double(p[0]) - s.position[0], double(p[1]) - s.position[1], double(p[2]) - s.position[2]};
  // rows of R (body to world), applied transposed
  const double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                          {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                          {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
  for (int i = 0; i < 3; ++i) out[i] = static_cast<float>(R[0][i] * r[0] + R[1][i] * r[1] + R[2][i] * r[2]);
}

}  // namespace

WorldCommands::WorldCommands(std::vector<unsigned char> initial, CommandLimits limits)
    : initial_(std::move(initial)), limits_(limits), world_(ppe::World::restore(initial_.data(), initial_.size())) {}

std::optional<CommandError> WorldCommands::check_drag(const char* type, uint32_t drag) const {
  if (drag >= drags_.size() || !drags_[drag].alive)
    return invalid(type, "drag", "no drag " + std::to_string(drag) + " is held in this world");
  return std::nullopt;
}

std::optional<CommandError> WorldCommands::check(const Command& c) const {
  const ppe::World& w = *world_;
  const ppe::WorldSettings& s = w.settings();
  switch (static_cast<Type>(c.type)) {
    case Type::spawn: {
      const auto m = c.as<protocol::Spawn>();
      const char* t = "spawn";
      if (m.shape >= w.shapes().size())
        return invalid(t, "shape", "no shape " + std::to_string(m.shape) + " (the dictionary has " +
                                       std::to_string(w.shapes().size()) + ")");
      if (w.shapes().is_static_only(m.shape))
        return invalid(t, "shape", "shape " + std::to_string(m.shape) + " is a " + spu::shape_type_name(w.shapes().type(m.shape)) +
                                       ": it is static level geometry and cannot be spawned");
      if (auto e = positive(t, "scale", m.scale, 1000.0)) return e;
      if (auto e = positive(t, "mass", m.mass, 1e9)) return e;
      if (!std::isfinite(m.friction) || m.friction < 0) return invalid(t, "friction", "must be a finite number >= 0");
      if (auto e = in_region(t, "position", m.position, s)) return e;
      if (auto e = finite(t, "orientation", m.orientation, 4)) return e;
      const double qn = std::sqrt(double(m.orientation[0]) * m.orientation[0] + double(m.orientation[1]) * m.orientation[1] +
                                  double(m.orientation[2]) * m.orientation[2] + double(m.orientation[3]) * m.orientation[3]);
      if (std::fabs(qn - 1.0) > 1e-3) return invalid(t, "orientation", "not a unit quaternion (its norm is " + num(qn) + ")");
      if (auto e = finite(t, "velocity", m.velocity, 3)) return e;
      if (length(m.velocity) > limits_.max_speed)
        return invalid(t, "velocity", "speed " + num(length(m.velocity)) + " m/s is more than " + num(limits_.max_speed));
      if (auto e = finite(t, "angular_velocity", m.angular_velocity, 3)) return e;
      if (length(m.angular_velocity) > limits_.max_angular_speed)
        return invalid(t, "angular_velocity", num(length(m.angular_velocity)) + " rad/s is more than " +
                                                  num(limits_.max_angular_speed));
      if (w.num_bodies() >= limits_.max_bodies)
        return invalid(t, "shape", "the world holds its limit of " + std::to_string(limits_.max_bodies) + " bodies");
      return std::nullopt;
    }
    case Type::remove: {
      return dynamic_body("remove", c.as<protocol::Remove>().body, w);
    }
    case Type::impulse: {
      const auto m = c.as<protocol::Impulse>();
      const char* t = "impulse";
      if (auto e = dynamic_body(t, m.body, w)) return e;
      if (auto e = finite(t, "impulse", m.impulse, 3)) return e;
      const double dv = length(m.impulse) / w.mass(m.body);
      if (dv > limits_.max_speed)
        return invalid(t, "impulse", "would change the body's speed by " + num(dv) + " m/s, more than " + num(limits_.max_speed));
      return in_region(t, "point", m.point, s);
    }
    case Type::drag_start: {
      const auto m = c.as<protocol::DragStart>();
      const char* t = "drag_start";
      if (auto e = dynamic_body(t, m.body, w)) return e;
      if (auto e = in_region(t, "point", m.point, s)) return e;
      if (auto e = in_region(t, "target", m.target, s)) return e;
      const double mass = w.mass(m.body), kmax = double(limits_.max_drag_stiffness_per_kg) * mass;
      if (!std::isfinite(m.stiffness) || m.stiffness < 0 || m.stiffness > kmax)
        return invalid(t, "stiffness", "must be from 0 (the default) to " + num(kmax) + " N/m for this body, got " + num(m.stiffness));
      const double cmax = 2.0 * std::sqrt(kmax * mass) * 10.0;
      if (!std::isfinite(m.damping) || m.damping < 0 || m.damping > cmax)
        return invalid(t, "damping", "must be from 0 (the default) to " + num(cmax) + " N s/m for this body, got " + num(m.damping));
      size_t held = 0;
      for (const Drag& d : drags_) held += d.alive;
      if (held >= limits_.max_drags)
        return invalid(t, "body", "the world holds its limit of " + std::to_string(limits_.max_drags) + " drags");
      return std::nullopt;
    }
    case Type::drag_move: {
      const auto m = c.as<protocol::DragMove>();
      if (auto e = check_drag("drag_move", m.drag)) return e;
      if (!w.has_body(drags_[m.drag].body))
        return invalid("drag_move", "drag", "drag " + std::to_string(m.drag) + "'s body was removed");
      return in_region("drag_move", "target", m.target, s);
    }
    case Type::drag_release:
      return check_drag("drag_release", c.as<protocol::DragRelease>().drag);
    case Type::pause:
    case Type::resume:
    case Type::step_once:
    case Type::reset:
      return std::nullopt;
    case Type::set_speed: {
      const float v = c.as<protocol::SetSpeed>().speed;
      if (!(v >= protocol::kMinSpeed && v <= protocol::kMaxSpeed))
        return invalid("set_speed", "speed",
                       num(v) + " is not from " + num(double(protocol::kMinSpeed), 3) + " to " +
                           num(double(protocol::kMaxSpeed), 3) + " (times real time)");
      return std::nullopt;
    }
    default:
      return CommandError{protocol::ErrorCode::malformed, "header.type",
                          "type " + std::to_string(c.type) + " is not a command"};
  }
}

ppe::ForceId WorldCommands::add_drag_force(const Drag& d, const float target[3]) {
  return world_->add_force("point_to_point", d.body, ppe::kWorldBody,
                           {{"point_a", {d.point_body[0], d.point_body[1], d.point_body[2]}},
                            {"point_b", {target[0], target[1], target[2]}},
                            {"stiffness", {d.stiffness}},
                            {"damping", {d.damping}}});
}

std::optional<CommandError> WorldCommands::apply(const Command& c, Applied& out) {
  if (auto e = check(c)) return e;
  out = Applied{};
  ppe::World& w = *world_;
  try {
    switch (static_cast<Type>(c.type)) {
      case Type::spawn: {
        const auto m = c.as<protocol::Spawn>();
        ppe::BodyDesc d;
        d.shape = m.shape;
        d.scale = m.scale;
        d.mass = m.mass;
        d.friction = m.friction;
        ppe::copy_state(m, d.state);
        out.result = w.add_body(d);
        break;
      }
      case Type::remove:
        w.remove_body(c.as<protocol::Remove>().body);
        break;
      case Type::impulse: {
        const auto m = c.as<protocol::Impulse>();
        w.apply_impulse(m.body, m.impulse, m.point);
        break;
      }
      case Type::drag_start: {
        const auto m = c.as<protocol::DragStart>();
        Drag d;
        d.alive = true;
        d.body = m.body;
        to_body(w.state(m.body), m.point, d.point_body);
        const double mass = w.mass(m.body), omega = 2.0 * kPi * kDragHertz;
        d.stiffness = m.stiffness > 0 ? m.stiffness : static_cast<float>(mass * omega * omega);
        d.damping = m.damping > 0 ? m.damping : static_cast<float>(2.0 * std::sqrt(double(d.stiffness) * mass));
        d.force = add_drag_force(d, m.target);
        out.result = static_cast<uint32_t>(drags_.size());
        drags_.push_back(d);
        break;
      }
      case Type::drag_move: {
        const auto m = c.as<protocol::DragMove>();
        Drag& d = drags_[m.drag];
        const ppe::ForceId next = add_drag_force(d, m.target);  // first, so a refusal leaves the old one
        w.remove_force(d.force);
        d.force = next;
        break;
      }
      case Type::drag_release: {
        Drag& d = drags_[c.as<protocol::DragRelease>().drag];
        if (w.has_body(d.body)) w.remove_force(d.force);  // a removed body took its forces with it
        d.alive = false;
        break;
      }
      case Type::reset:
        world_ = ppe::World::restore(initial_.data(), initial_.size());
        drags_.clear();
        out.reset = true;
        break;
      default:
        break;  // pause, resume, step_once, set_speed: the caller's
    }
  } catch (const ppe::WorldError& e) {
    return CommandError{protocol::ErrorCode::invalid, protocol::type_name(c.type), e.what()};
  }
  return std::nullopt;
}

}  // namespace cellphys::server

// The world's queries between steps: each checks its arguments, brings the query tree up to
// date (runtime/ppe/query_tree.h), walks it to the bodies whose boxes the query reaches, and
// tests their exact shapes (shape_ray.h, shape_distance.h, shape_sweep.h); planes, unbounded,
// are tested on every query.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "runtime/base/quat.h"
#include "runtime/ppe/shape_distance.h"
#include "runtime/ppe/shape_ray.h"
#include "runtime/ppe/shape_sweep.h"
#include "runtime/ppe/world.h"
#include "runtime/ppe/world_impl.h"

namespace cellphys::ppe {

namespace {

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}
std::string vec(const float* v, int n) {
  std::string s = "(";
  for (int k = 0; k < n; ++k) s += (k ? ", " : "") + num(v[k]);
  return s + ")";
}

Vec3d finite_point(const char* query, const char* arg, const float* v) {
  if (!v) throw WorldError(std::string(query) + ": " + arg + " is missing");
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(v[k])) throw WorldError(std::string(query) + ": " + arg + " is not finite " + vec(v, 3));
  return Vec3d::load(v);
}

Vec3d unit_direction(const char* query, const char* arg, const float* v) {
  const Vec3d d = finite_point(query, arg, v);
  const double l = norm(d);
  if (!(l > 0.0) || !std::isfinite(l)) throw WorldError(std::string(query) + ": " + arg + " is zero");
  return d * (1.0 / l);
}

double max_distance(const char* query, float d) {
  if (!(d >= 0.0f)) throw WorldError(std::string(query) + ": max_dist must be >= 0 (infinite allowed), got " + num(d));
  return d;
}

float positive(const char* query, const char* arg, float v) {
  if (!(v > 0.0f) || !std::isfinite(v))
    throw WorldError(std::string(query) + ": " + arg + " must be positive and finite, got " + num(v));
  return v;
}

// A unit orientation; refuses a missing, non-finite or zero one.
void unit_orientation(const char* query, const float* q, float out[4]) {
  if (!q) throw WorldError(std::string(query) + ": orientation is missing");
  for (int k = 0; k < 4; ++k)
    if (!std::isfinite(q[k])) throw WorldError(std::string(query) + ": orientation is not finite " + vec(q, 4));
  const double n = norm(Quatd::load(q));
  if (!(n > 0.0)) throw WorldError(std::string(query) + ": orientation is zero");
  for (int k = 0; k < 4; ++k) out[k] = float(q[k] / n);
}

bool passes(const WorldBody& b, BodyId id, const QueryFilter& f) {
  if (b.is_static ? !f.static_bodies : (b.awake ? !f.awake_bodies : !f.sleeping_bodies)) return false;
  if (b.sensor && !f.sensors) return false;
  return !f.accept || f.accept(id);
}

QueryHit to_hit(BodyId id, const Vec3d& point, const Vec3d& normal, double distance) {
  QueryHit h;
  h.body = id;
  for (int k = 0; k < 3; ++k) h.point[k] = float(point[k]), h.normal[k] = float(normal[k]);
  h.distance = float(distance);
  return h;
}

// Half extents of the world box of a query shape at rotation R (symmetric about its centre).
Vec3d world_half(const spu::ShapeView& v, const Mat3d& R) {
  Vec3d h{};
  for (int k = 0; k < 3; ++k) {
    double e = 0.0;
    if (v.type == spu::ShapeType::sphere) e = v.radius;
    if (v.type == spu::ShapeType::capsule) e = v.radius + std::fabs(R.m[k][2]) * v.half_height;
    if (v.type == spu::ShapeType::box)
      e = std::fabs(R.m[k][0]) * v.half_extents[0] + std::fabs(R.m[k][1]) * v.half_extents[1] +
          std::fabs(R.m[k][2]) * v.half_extents[2];
    (k == 0 ? h.x : k == 1 ? h.y : h.z) = e * (1.0 + 1e-6);  // rounded outward
  }
  return h;
}

Aabb box_around(const Vec3d& c, const Vec3d& h) {
  Aabb b;
  for (int k = 0; k < 3; ++k) {
    b.min[k] = std::nextafter(float(c[k] - h[k]), -std::numeric_limits<float>::infinity());
    b.max[k] = std::nextafter(float(c[k] + h[k]), std::numeric_limits<float>::infinity());
  }
  return b;
}

bool nearer(double t, BodyId id, double best_t, BodyId best_id) { return t < best_t || (t == best_t && id < best_id); }

}  // namespace

std::optional<QueryHit> World::ray_cast(const float origin[3], const float dir[3], float max_dist,
                                        const QueryFilter& filter) const {
  const Vec3d o = finite_point("ray_cast", "origin", origin), d = unit_direction("ray_cast", "dir", dir);
  const double reach = max_distance("ray_cast", max_dist);
  const Impl& w = *impl_;
  w.queries.update(w.bodies, shapes_, w.revision);
  bool found = false;
  BodyId best = 0;
  ShapeRayHit hit, h;
  hit.distance = reach;
  auto test = [&](uint32_t id, double& max_t) {
    const WorldBody& b = w.bodies[id];
    if (!passes(b, id, filter) || !ray_shape(shapes_.view(b.shape), pose_of(b), o, d, max_t, h)) return;
    if (found && !nearer(h.distance, id, hit.distance, best)) return;
    found = true, best = id, hit = h, max_t = h.distance;
  };
  w.queries.tree().ray(o, d, reach, Vec3d{}, test);
  double plane_t = hit.distance;
  for (uint32_t p : w.queries.planes()) test(p, plane_t);
  if (!found) return std::nullopt;
  return to_hit(best, hit.point, hit.normal, hit.distance);
}

std::vector<QueryHit> World::ray_cast_all(const float origin[3], const float dir[3], float max_dist,
                                          const QueryFilter& filter) const {
  const Vec3d o = finite_point("ray_cast_all", "origin", origin), d = unit_direction("ray_cast_all", "dir", dir);
  const double reach = max_distance("ray_cast_all", max_dist);
  const Impl& w = *impl_;
  w.queries.update(w.bodies, shapes_, w.revision);
  std::vector<std::pair<double, QueryHit>> hits;
  ShapeRayHit h;
  auto test = [&](uint32_t id, double&) {
    const WorldBody& b = w.bodies[id];
    if (passes(b, id, filter) && ray_shape(shapes_.view(b.shape), pose_of(b), o, d, reach, h))
      hits.emplace_back(h.distance, to_hit(id, h.point, h.normal, h.distance));
  };
  w.queries.tree().ray(o, d, reach, Vec3d{}, test);
  double unused = reach;
  for (uint32_t p : w.queries.planes()) test(p, unused);
  std::sort(hits.begin(), hits.end(), [](const auto& a, const auto& b) {
    return a.first < b.first || (a.first == b.first && a.second.body < b.second.body);
  });
  std::vector<QueryHit> out;
  out.reserve(hits.size());
  for (const auto& x : hits) out.push_back(x.second);
  return out;
}

namespace {

// Bodies overlapping a query shape whose world box is `box`, ids ascending.
template <class Index>
std::vector<BodyId> overlapping(const Index& index, const std::vector<WorldBody>& bodies, const ShapeDictionary& shapes,
                                const spu::ShapeView& q, const spu::Pose& pose, const Aabb& box,
                                const QueryFilter& filter) {
  std::vector<BodyId> out;
  auto test = [&](uint32_t id) {
    const WorldBody& b = bodies[id];
    if (passes(b, id, filter) && shapes_overlap(q, pose, shapes.view(b.shape), pose_of(b))) out.push_back(id);
  };
  index.tree().overlap(box, test);
  for (uint32_t p : index.planes()) test(p);
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

std::vector<BodyId> World::overlap_sphere(const float centre[3], float radius, const QueryFilter& filter) const {
  const Vec3d c = finite_point("overlap_sphere", "centre", centre);
  spu::ShapeView q;
  q.type = spu::ShapeType::sphere;
  q.radius = positive("overlap_sphere", "radius", radius);
  spu::Pose pose;
  std::copy(centre, centre + 3, pose.position);
  const Impl& w = *impl_;
  w.queries.update(w.bodies, shapes_, w.revision);
  return overlapping(w.queries, w.bodies, shapes_, q, pose, box_around(c, world_half(q, Mat3d{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}})),
                     filter);
}

std::vector<BodyId> World::overlap_box(const float centre[3], const float half_extents[3], const float orientation[4],
                                       const QueryFilter& filter) const {
  const Vec3d c = finite_point("overlap_box", "centre", centre);
  if (!half_extents) throw WorldError("overlap_box: half_extents is missing");
  spu::ShapeView q;
  q.type = spu::ShapeType::box;
  const char* names[3] = {"half_extents x", "half_extents y", "half_extents z"};
  for (int k = 0; k < 3; ++k) q.half_extents[k] = positive("overlap_box", names[k], half_extents[k]);
  spu::Pose pose;
  std::copy(centre, centre + 3, pose.position);
  unit_orientation("overlap_box", orientation, pose.orientation);
  const Impl& w = *impl_;
  w.queries.update(w.bodies, shapes_, w.revision);
  const Aabb box = box_around(c, world_half(q, quat_to_matrix(Quatd::load(pose.orientation))));
  return overlapping(w.queries, w.bodies, shapes_, q, pose, box, filter);
}

std::optional<QueryHit> World::shape_cast(const QueryShape& shape, const float position[3], const float orientation[4],
                                          const float dir[3], float max_dist, const QueryFilter& filter) const {
  finite_point("shape_cast", "position", position);
  const Vec3d d = unit_direction("shape_cast", "dir", dir);
  const double reach = max_distance("shape_cast", max_dist);
  spu::ShapeView q;
  q.type = shape.type;
  switch (shape.type) {
    case spu::ShapeType::sphere: q.radius = positive("shape_cast", "shape radius", shape.radius); break;
    case spu::ShapeType::capsule:
      q.radius = positive("shape_cast", "shape radius", shape.radius);
      q.half_height = positive("shape_cast", "shape half_height", shape.half_height);
      break;
    case spu::ShapeType::box: {
      const char* names[3] = {"shape half_extents x", "shape half_extents y", "shape half_extents z"};
      for (int k = 0; k < 3; ++k) q.half_extents[k] = positive("shape_cast", names[k], shape.half_extents[k]);
      break;
    }
    default:
      throw WorldError(std::string("shape_cast: shape must be a sphere, capsule or box, got ") +
                       spu::shape_type_name(shape.type));
  }
  spu::Pose pose;
  std::copy(position, position + 3, pose.position);
  unit_orientation("shape_cast", orientation, pose.orientation);
  const Impl& w = *impl_;
  w.queries.update(w.bodies, shapes_, w.revision);
  // The tree is walked by the shape's centre with every box grown by the shape's half extents
  // and the sweep's tolerance (a sweep hits where the shapes come that near).
  const Vec3d grow = world_half(q, quat_to_matrix(Quatd::load(pose.orientation))) +
                     Vec3d{1, 1, 1} * (2.0 * kSweepTolerance);
  bool found = false;
  BodyId best = 0;
  SweepHit hit, h;
  hit.distance = reach;
  auto test = [&](uint32_t id, double& max_t) {
    const WorldBody& b = w.bodies[id];
    if (!passes(b, id, filter) || !sweep_shape(q, pose, d, max_t, shapes_.view(b.shape), pose_of(b), h)) return;
    if (found && !nearer(h.distance, id, hit.distance, best)) return;
    found = true, best = id, hit = h, max_t = h.distance;
  };
  w.queries.tree().ray(Vec3d::load(position), d, reach, grow, test);
  double plane_t = hit.distance;
  for (uint32_t p : w.queries.planes()) test(p, plane_t);
  if (!found) return std::nullopt;
  return to_hit(best, hit.point, hit.normal, hit.distance);
}

}  // namespace cellphys::ppe

// What the world's queries take and give (World::ray_cast, ray_cast_all, overlap_sphere,
// overlap_box, shape_cast; runtime/ppe/world_queries.cpp, docs/queries.md).
#pragma once
#include <cstdint>
#include <functional>

#include "runtime/spu/shape.h"

namespace cellphys::ppe {

using BodyId = uint32_t;  // as in world.h

/// Which bodies a query sees. Static bodies include planes; sleeping bodies are dynamic ones
/// asleep. `accept`, when set, has the last word on each body the flags let through.
struct QueryFilter {
  bool static_bodies = true;
  bool awake_bodies = true;
  bool sleeping_bodies = true;
  bool sensors = false;  // sensors (BodyDesc::sensor) are left out unless asked for: a shot passes a trigger
  std::function<bool(BodyId)> accept;
};

/// Where a ray or a swept shape first meets a body.
struct QueryHit {
  BodyId body = 0;
  float point[3] = {};   // world, on the body's surface
  float normal[3] = {};  // the body's outward unit surface normal there
  float distance = 0.0f;  // along the unit direction from the origin (m)
};

/// A shape to sweep (World::shape_cast): a sphere, a capsule along its local z, or a box.
struct QueryShape {
  spu::ShapeType type = spu::ShapeType::sphere;
  float radius = 0.0f;          // sphere, capsule
  float half_height = 0.0f;     // capsule: the core runs from -half_height to +half_height on z
  float half_extents[3] = {};   // box

  static QueryShape sphere(float radius) { return {spu::ShapeType::sphere, radius, 0.0f, {}}; }
  static QueryShape capsule(float radius, float half_height) {
    return {spu::ShapeType::capsule, radius, half_height, {}};
  }
  static QueryShape box(const float half[3]) { return {spu::ShapeType::box, 0.0f, 0.0f, {half[0], half[1], half[2]}}; }
};

}  // namespace cellphys::ppe

// Collision shapes as the narrow phase reads them: plain views onto packed shape data, in
// body coordinates at unit scale (a body scales its dictionary shape uniformly).
#pragma once
#include <cstdint>

#include "runtime/base/enum_names.h"

namespace cellphys::spu {

// The values are stored in world snapshots (runtime/ppe/snapshot.cpp): new types go at the end.
enum class ShapeType : uint32_t { sphere = 0, capsule = 1, box = 2, hull = 3, plane = 4 };
inline constexpr uint32_t kNumShapeTypes = 5;

/// The names as scene files and messages spell them, in value order.
inline constexpr const char* kShapeTypeNames[kNumShapeTypes] = {"sphere", "capsule", "box", "hull", "plane"};
/// The type's name ("shape" for a value out of range).
constexpr const char* shape_type_name(ShapeType t) { return base::name_of(kShapeTypeNames, t, "shape"); }

/// A convex polyhedron. Faces are outward planes n.x = d (|n| = 1) with their vertex loops,
/// counter-clockwise seen from outside; every undirected edge is listed once.
struct HullView {
  int32_t num_vertices = 0;
  const float* vertices = nullptr;  // 3 floats each
  int32_t num_faces = 0;
  const float* planes = nullptr;           // 4 floats each: nx ny nz d
  const int32_t* face_start = nullptr;     // num_faces + 1
  const int32_t* face_vertices = nullptr;  // vertex indices of every face loop
  int32_t num_edges = 0;
  const int32_t* edges = nullptr;  // 2 vertex indices each
};

struct ShapeView {
  ShapeType type = ShapeType::sphere;
  float radius = 0.0f;           // sphere, capsule
  float half_height = 0.0f;      // capsule: the core segment runs from -half_height to +half_height on body z
  float half_extents[3] = {};    // box
  float normal[3] = {0, 0, 1};   // plane (static, world frame): n.x = offset
  float offset = 0.0f;
  HullView hull;                 // hull
};

/// A body's world pose: position and unit quaternion (w x y z), and its uniform scale.
struct Pose {
  float position[3] = {};
  float orientation[4] = {1, 0, 0, 0};
  float scale = 1.0f;
};

/// One contact point: world point midway between the surfaces, unit normal from a to b,
/// and penetration depth (> 0 when overlapping).
struct ContactPoint {
  float point[3];
  float normal[3];
  float penetration;
};

inline constexpr int kMaxManifoldPoints = 4;

}  // namespace cellphys::spu

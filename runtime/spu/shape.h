// Collision shapes as the narrow phase reads them: plain views onto packed shape data, in
// body coordinates at unit scale (a body scales its dictionary shape uniformly).
#pragma once
#include <cstdint>

#include "runtime/base/enum_names.h"

namespace cellphys::spu {

// The values are stored in world snapshots (runtime/ppe/snapshot.cpp): new types go at the end.
enum class ShapeType : uint32_t { sphere = 0, capsule = 1, box = 2, hull = 3, plane = 4, mesh = 5, height_field = 6 };
inline constexpr uint32_t kNumShapeTypes = 7;

/// The names as scene files and messages spell them, in value order.
inline constexpr const char* kShapeTypeNames[kNumShapeTypes] = {"sphere", "capsule", "box", "hull", "plane", "mesh",
                                                                "height_field"};
/// The type's name ("shape" for a value out of range).
constexpr const char* shape_type_name(ShapeType t) { return base::name_of(kShapeTypeNames, t, "shape"); }

/// Level geometry: static triangle surfaces, collided one triangle at a time (a height field is
/// stored as its triangles too). Neither can be dynamic.
constexpr bool is_triangle_surface(ShapeType t) { return t == ShapeType::mesh || t == ShapeType::height_field; }

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

/// A node of a triangle surface's bounding volume hierarchy (body coordinates, unit scale). A
/// leaf (count > 0) holds triangles first .. first + count - 1; an inner node's children are
/// nodes first and first + 1.
struct MeshNode {
  float min[3], max[3];
  int32_t first = 0, count = 0;
};

/// A one-sided triangle surface: a triangle's front is where its vertices run counter-clockwise.
/// Per triangle, edge k runs from vertex k to vertex k + 1 (mod 3); bit k of its edge flags is
/// set when that edge is *active*: on the surface's border, or a convex crease sharper than the
/// surface's flat angle. A contact on an inactive edge (shared with a neighbour in the same
/// plane, or in a hollow) takes the triangle's normal, so nothing snags on the inside edges of
/// a flat or smooth surface.
struct MeshView {
  int32_t num_vertices = 0;
  const float* vertices = nullptr;    // 3 floats each
  int32_t num_triangles = 0;
  const int32_t* triangles = nullptr;  // 3 vertex indices each, in the hierarchy's leaf order
  const float* normals = nullptr;      // 3 floats each: the unit front normal
  const uint8_t* edge_flags = nullptr;  // per triangle
  int32_t num_nodes = 0;
  const MeshNode* nodes = nullptr;     // node 0 is the root
};

struct ShapeView {
  ShapeType type = ShapeType::sphere;
  float radius = 0.0f;           // sphere, capsule
  float half_height = 0.0f;      // capsule: the core segment runs from -half_height to +half_height on body z
  float half_extents[3] = {};    // box
  float normal[3] = {0, 0, 1};   // plane (static, world frame): n.x = offset
  float offset = 0.0f;
  HullView hull;                 // hull
  MeshView mesh;                 // mesh, height_field
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

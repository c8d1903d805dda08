// Collision shapes as the narrow phase reads them: plain views onto packed shape data, in
// body coordinates at unit scale (a body scales its dictionary shape uniformly).
#pragma once
#include <cstdint>

#include "runtime/base/enum_names.h"

namespace cellphys::spu {

// The values are stored in world snapshots (runtime/ppe/snapshot.cpp): new types go at the end.
enum class ShapeType : uint32_t {
  sphere = 0, capsule = 1, box = 2, hull = 3, plane = 4, mesh = 5, height_field = 6, compound = 7
};
inline constexpr uint32_t kNumShapeTypes = 8;

/// The names as scene files and messages spell them, in value order.
inline constexpr const char* kShapeTypeNames[kNumShapeTypes] = {"sphere", "capsule", "box", "hull", "plane", "mesh",
                                                                "height_field", "compound"};
/// The type's name ("shape" for a value out of range).
constexpr const char* shape_type_name(ShapeType t) { return base::name_of(kShapeTypeNames, t, "shape"); }

/// Level geometry: static triangle surfaces, collided one triangle at a time (a height field is
/// stored as its triangles too). Neither can be dynamic.
constexpr bool is_triangle_surface(ShapeType t) { return t == ShapeType::mesh || t == ShapeType::height_field; }
/// The shapes a compound is made of, and that collide one with another directly.
constexpr bool is_convex(ShapeType t) {
  return t == ShapeType::sphere || t == ShapeType::capsule || t == ShapeType::box || t == ShapeType::hull;
}

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

struct ShapeView;

/// A body made of several convex shapes: each part a dictionary shape at a pose in the body's
/// frame (its scale multiplies the part's own, the body's multiplies both). The dictionary
/// re-centres the parts on their common centre of mass.
struct CompoundPartView {
  const ShapeView* shape = nullptr;
  float position[3] = {};
  float orientation[4] = {1, 0, 0, 0};  // unit
  float scale = 1.0f;
};
struct CompoundView {
  int32_t num_parts = 0;
  const CompoundPartView* parts = nullptr;
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
  CompoundView compound;         // compound
};

/// A body's world pose: position and unit quaternion (w x y z), and its uniform scale.
struct Pose {
  float position[3] = {};
  float orientation[4] = {1, 0, 0, 0};
  float scale = 1.0f;
};

/// The world pose of part `part` of a compound at `body`: the part's pose composed with the
/// body's, scales multiplied.
inline Pose part_pose(const Pose& body, const CompoundPartView& part) {
  const float* q = body.orientation;
  const float* r = part.orientation;
  Pose p;
  // position: body position + R(body) (body scale * part position)
  const float x = part.position[0] * body.scale, y = part.position[1] * body.scale, z = part.position[2] * body.scale;
  const float w = q[0], a = q[1], b = q[2], c = q[3];
  // t = 2 q_vec x v; v' = v + w t + q_vec x t (a unit quaternion's rotation)
  const float tx = 2 * (b * z - c * y), ty = 2 * (c * x - a * z), tz = 2 * (a * y - b * x);
  p.position[0] = body.position[0] + x + w * tx + (b * tz - c * ty);
  p.position[1] = body.position[1] + y + w * ty + (c * tx - a * tz);
  p.position[2] = body.position[2] + z + w * tz + (a * ty - b * tx);
  p.orientation[0] = w * r[0] - a * r[1] - b * r[2] - c * r[3];
  p.orientation[1] = w * r[1] + a * r[0] + b * r[3] - c * r[2];
  p.orientation[2] = w * r[2] - a * r[3] + b * r[0] + c * r[1];
  p.orientation[3] = w * r[3] + a * r[2] - b * r[1] + c * r[0];
  p.scale = body.scale * part.scale;
  return p;
}

/// One contact point: world point midway between the surfaces, unit normal from a to b,
/// and penetration depth (> 0 when overlapping).
struct ContactPoint {
  float point[3];
  float normal[3];
  float penetration;
};

inline constexpr int kMaxManifoldPoints = 4;

}  // namespace cellphys::spu

// The shape dictionary: every collision shape is stored once and bodies refer to it by index
// plus a uniform scale (the reference design's compressed shape reference), so geometry never travels
// with a body. Entries are immutable once added and their views stay valid for the
// dictionary's lifetime, so the narrow phase may hold on to them.
#pragma once
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <vector>

#include "runtime/spu/shape.h"

namespace cellphys::ppe {

/// Bad shape input (or a request a shape cannot answer); the message names the shape kind.
class ShapeError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// Bounds on hull input and output, so a hull fits the compute side's local store.
struct HullLimits {
  int max_points = 4096;   // input point cloud
  int max_vertices = 256;  // vertices of the resulting hull
};

/// What add_hull made of its input.
struct HullInfo {
  /// The hull's centre of mass in input coordinates. Stored vertices are input points minus
  /// this, so the body origin is the centre of mass: a body whose input origin belongs at p
  /// with rotation R and scale s goes at p + R (s * shift).
  float shift[3] = {};
  int32_t num_input_points = 0;
  int32_t num_vertices = 0, num_faces = 0, num_edges = 0;
};

/// What a triangle surface (mesh or height field) was made from, as given: files and snapshots
/// rebuild it from this, so a restored surface is the same bit for bit.
struct SurfaceInput {
  std::vector<float> vertices;     // mesh: 3 floats a vertex
  std::vector<int32_t> triangles;  // mesh: 3 vertex indices a triangle, counter-clockwise seen from the front
  int32_t rows = 0, columns = 0;   // height field: the grid
  float spacing[2] = {};           // height field: between columns (x) and rows (y)
  std::vector<float> heights;      // height field: rows x columns, row-major
  int32_t dropped_triangles = 0;   // triangles with no area, left out
  int32_t num_triangles = 0;       // the triangles the surface holds
};

/// A part of a compound as given: a shape of the dictionary (sphere, capsule, box or hull) at a
/// pose in the compound's frame, with its own uniform scale.
struct CompoundPart {
  uint32_t shape = 0;
  float position[3] = {};
  float orientation[4] = {1, 0, 0, 0};  // normalised by add_compound
  float scale = 1.0f;
};

/// What add_compound made of its parts.
struct CompoundInfo {
  /// The parts' common centre of mass (uniform density) in input coordinates; the stored parts
  /// are moved by minus this, as a hull's vertices are (HullInfo::shift).
  float shift[3] = {};
};

inline constexpr int kMaxCompoundParts = 64;

class ShapeDictionary {
 public:
  explicit ShapeDictionary(HullLimits limits = {});
  ~ShapeDictionary();
  ShapeDictionary(ShapeDictionary&&) noexcept;
  ShapeDictionary& operator=(ShapeDictionary&&) noexcept;
  ShapeDictionary(const ShapeDictionary&) = delete;
  ShapeDictionary& operator=(const ShapeDictionary&) = delete;

  // Each returns the new index, or throws ShapeError and adds nothing.
  uint32_t add_sphere(float radius);
  /// Core segment from -half_height to +half_height on body z.
  uint32_t add_capsule(float radius, float half_height);
  uint32_t add_box(const float half_extents[3]);
  /// Convex hull of a point cloud (3 floats a point), re-centred on its centre of mass. With
  /// `recentre` false the points are taken where they are: a hull this dictionary made (a
  /// snapshot's) is on its centre of mass already, to rounding, and moving it again by that
  /// rounding would change its bits.
  uint32_t add_hull(const float* points, int count, HullInfo* info = nullptr, bool recentre = true);
  /// Static half-space n.x <= offset in world coordinates; the normal is normalised.
  uint32_t add_plane(const float normal[3], float offset);
  /// Static one-sided triangle mesh in body coordinates (runtime/ppe/triangle_surface.h says what
  /// is refused); triangles with no area are left out and counted in surface_input().
  uint32_t add_mesh(const float* vertices, int num_vertices, const int32_t* triangles, int num_triangles);
  /// Static height field: rows x columns heights along body z, row-major, spaced spacing[0]
  /// along x and spacing[1] along y, centred on the body origin.
  uint32_t add_height_field(int rows, int columns, const float spacing[2], const float* heights);
  /// A body of 1 to kMaxCompoundParts convex parts (runtime/spu/shape.h: CompoundView), re-centred
  /// on their centre of mass at uniform density (`recentre` false takes them where they are: a
  /// snapshot's are centred already). Throws ShapeError naming the part: a shape that does not
  /// exist or is not convex, a pose that is not finite, a zero orientation, a scale that is not
  /// positive.
  uint32_t add_compound(const CompoundPart* parts, int count, CompoundInfo* info = nullptr, bool recentre = true);
  /// The parts as stored (re-centred); throws ShapeError if the entry is not a compound.
  const std::vector<CompoundPart>& compound_parts(uint32_t index) const;

  size_t size() const { return entries_.size(); }
  spu::ShapeType type(uint32_t index) const;
  /// Unit-scale view for the narrow phase; valid as long as the dictionary lives.
  const spu::ShapeView& view(uint32_t index) const;
  /// Throws ShapeError if the entry is not a hull.
  const HullInfo& hull_info(uint32_t index) const;
  /// Throws ShapeError if the entry is not a mesh or a height field.
  const SurfaceInput& surface_input(uint32_t index) const;
  /// Planes: unbounded, never dynamic.
  bool is_static_infinite(uint32_t index) const;
  /// Planes, meshes and height fields: a body of this shape is static.
  bool is_static_only(uint32_t index) const;

  /// Box in body coordinates at a scale. Planes give their world half-space bound
  /// (finite only on the axis an axis-aligned normal points along), +-infinity elsewhere.
  void local_aabb(uint32_t index, float scale, float min[3], float max[3]) const;
  /// World box for a body pose (pose.scale applies); tight for spheres, capsules, boxes and
  /// hulls (hull vertices are transformed), rounded outward to float.
  void world_aabb(uint32_t index, const spu::Pose& pose, float min[3], float max[3]) const;

  /// Bytes of geometry stored (all shapes, or one): what sending geometry would cost,
  /// against a 4-byte index and a scale per body.
  size_t bytes() const { return bytes_; }
  size_t bytes(uint32_t index) const;
  const HullLimits& limits() const { return limits_; }

 private:
  struct Entry;
  const Entry& entry(uint32_t index) const;
  uint32_t push(std::unique_ptr<Entry> e);
  uint32_t push_surface(std::unique_ptr<Entry> e);

  HullLimits limits_;
  std::vector<std::unique_ptr<Entry>> entries_;  // heap entries: views never move
  size_t bytes_ = 0;
};

}  // namespace cellphys::ppe

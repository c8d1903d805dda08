#include "runtime/ppe/shapes.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>

#include "runtime/base/quat.h"
#include "runtime/ppe/convex_hull.h"
#include "runtime/ppe/mass_properties.h"
#include "runtime/ppe/outward_rounding.h"
#include "runtime/ppe/triangle_surface.h"

namespace cellphys::ppe {

struct ShapeDictionary::Entry {
  spu::ShapeView view;
  ConvexHull hull;  // hulls only; view.hull points into it
  HullInfo info;
  TriangleSurface surface;  // meshes and height fields; view.mesh points into it
  std::vector<CompoundPart> parts;            // compounds, as stored
  std::vector<spu::CompoundPartView> part_views;  // view.compound points into it
  SurfaceInput input;       // what they were made from
  double lo[3] = {}, hi[3] = {};  // hull, mesh and height-field box at unit scale
  size_t bytes = 0;
};

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

void require_positive(const char* shape, const char* what, float v) {
  if (!(v > 0.0f) || !std::isfinite(v))
    throw ShapeError(std::string(shape) + ": " + what + " must be positive and finite, got " + num(v));
}

// Boxes are rounded outward so the float box always contains the double one.
void store(const double lo[3], const double hi[3], float min[3], float max[3]) {
  for (int k = 0; k < 3; ++k) min[k] = round_down(lo[k]), max[k] = round_up(hi[k]);
}

// The half-space n.x <= offset is bounded only along an axis its normal points exactly along.
void plane_box(const spu::ShapeView& v, float min[3], float max[3]) {
  double lo[3] = {-kInf, -kInf, -kInf}, hi[3] = {kInf, kInf, kInf};
  for (int k = 0; k < 3; ++k) {
    const bool axis = v.normal[(k + 1) % 3] == 0.0f && v.normal[(k + 2) % 3] == 0.0f;
    if (axis && v.normal[k] == 1.0f) hi[k] = v.offset;
    if (axis && v.normal[k] == -1.0f) lo[k] = -static_cast<double>(v.offset);
  }
  store(lo, hi, min, max);
}

Mat3d rotation(const float orientation[4]) {
  const Quatd q = Quatd::load(orientation);
  const double n = norm(q);
  if (!(n > 0.0) || !std::isfinite(n)) throw ShapeError("world_aabb: pose orientation is not a usable quaternion");
  return quat_to_matrix(quat_normalized(q));
}

}  // namespace

ShapeDictionary::ShapeDictionary(HullLimits limits) : limits_(limits) {
  if (limits.max_points < 4 || limits.max_vertices < 4)
    throw ShapeError("hull limits: max_points and max_vertices must be at least 4");
}
ShapeDictionary::~ShapeDictionary() = default;
ShapeDictionary::ShapeDictionary(ShapeDictionary&&) noexcept = default;
ShapeDictionary& ShapeDictionary::operator=(ShapeDictionary&&) noexcept = default;

uint32_t ShapeDictionary::push(std::unique_ptr<Entry> e) {
  if (entries_.size() >= std::numeric_limits<uint32_t>::max())
    throw ShapeError(std::string(spu::shape_type_name(e->view.type)) + ": the shape dictionary is full");
  const size_t b = e->bytes;
  entries_.push_back(std::move(e));
  bytes_ += b;
  return static_cast<uint32_t>(entries_.size() - 1);
}

uint32_t ShapeDictionary::add_sphere(float radius) {
  require_positive("sphere", "radius", radius);
  auto e = std::make_unique<Entry>();
  e->view.type = spu::ShapeType::sphere;
  e->view.radius = radius;
  e->bytes = sizeof(float);
  return push(std::move(e));
}

uint32_t ShapeDictionary::add_capsule(float radius, float half_height) {
  require_positive("capsule", "radius", radius);
  require_positive("capsule", "half height", half_height);
  auto e = std::make_unique<Entry>();
  e->view.type = spu::ShapeType::capsule;
  e->view.radius = radius;
  e->view.half_height = half_height;
  e->bytes = 2 * sizeof(float);
  return push(std::move(e));
}

uint32_t ShapeDictionary::add_box(const float half_extents[3]) {
  if (!half_extents) throw ShapeError("box: no half extents given");
  require_positive("box", "half extent x", half_extents[0]);
  require_positive("box", "half extent y", half_extents[1]);
  require_positive("box", "half extent z", half_extents[2]);
  auto e = std::make_unique<Entry>();
  e->view.type = spu::ShapeType::box;
  for (int k = 0; k < 3; ++k) e->view.half_extents[k] = half_extents[k];
  e->bytes = 3 * sizeof(float);
  return push(std::move(e));
}

uint32_t ShapeDictionary::add_plane(const float normal[3], float offset) {
  if (!normal) throw ShapeError("plane: no normal given");
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(normal[k])) throw ShapeError("plane: normal is not finite (" + num(normal[k]) + ")");
  if (!std::isfinite(offset)) throw ShapeError("plane: offset is not finite (" + num(offset) + ")");
  const double n = norm(Vec3d::load(normal));
  if (!(n > 1e-30)) throw ShapeError("plane: normal is zero");
  auto e = std::make_unique<Entry>();
  e->view.type = spu::ShapeType::plane;
  for (int k = 0; k < 3; ++k) e->view.normal[k] = static_cast<float>(normal[k] / n);
  e->view.offset = offset;
  e->bytes = 4 * sizeof(float);
  return push(std::move(e));
}

uint32_t ShapeDictionary::add_hull(const float* points, int count, HullInfo* info, bool recentre) {
  ConvexHull h = compute_convex_hull(points, count, limits_);
  const MassProperties m = polyhedron_mass_properties(h.view());
  if (!(m.volume > 0.0) || !std::isfinite(m.volume)) throw ShapeError("hull: the hull has no positive, finite volume");
  if (recentre) {
    const double shift[3] = {-m.center_of_mass[0], -m.center_of_mass[1], -m.center_of_mass[2]};
    translate_hull(h, shift);
  }

  auto e = std::make_unique<Entry>();
  e->hull = std::move(h);
  e->view.type = spu::ShapeType::hull;
  e->view.hull = e->hull.view();
  HullInfo& hi = e->info;
  for (int k = 0; k < 3; ++k) hi.shift[k] = recentre ? static_cast<float>(m.center_of_mass[k]) : 0.0f;
  hi.num_input_points = count;
  hi.num_vertices = e->hull.num_vertices();
  hi.num_faces = e->hull.num_faces();
  hi.num_edges = e->hull.num_edges();
  for (int k = 0; k < 3; ++k) e->lo[k] = kInf, e->hi[k] = -kInf;
  for (int v = 0; v < hi.num_vertices; ++v)
    for (int k = 0; k < 3; ++k) {
      const double x = e->hull.vertices[3 * v + k];
      e->lo[k] = std::min(e->lo[k], x), e->hi[k] = std::max(e->hi[k], x);
    }
  const ConvexHull& c = e->hull;
  e->bytes = sizeof(float) * (c.vertices.size() + c.planes.size()) +
             sizeof(int32_t) * (c.face_start.size() + c.face_vertices.size() + c.edges.size());
  const HullInfo copy = hi;
  const uint32_t index = push(std::move(e));
  if (info) *info = copy;
  return index;
}

uint32_t ShapeDictionary::add_mesh(const float* vertices, int num_vertices, const int32_t* triangles, int num_triangles) {
  auto e = std::make_unique<Entry>();
  e->surface = build_triangle_surface("mesh", vertices, num_vertices, triangles, num_triangles);
  e->input.vertices.assign(vertices, vertices + 3 * size_t(num_vertices));
  e->input.triangles.assign(triangles, triangles + 3 * size_t(num_triangles));
  e->view.type = spu::ShapeType::mesh;
  return push_surface(std::move(e));
}

uint32_t ShapeDictionary::add_height_field(int rows, int columns, const float spacing[2], const float* heights) {
  if (!spacing || !heights) throw ShapeError("height_field: no spacing or heights given");
  std::vector<float> vertices;
  std::vector<int32_t> triangles;
  height_field_triangles(rows, columns, spacing, heights, vertices, triangles);
  auto e = std::make_unique<Entry>();
  e->surface = build_triangle_surface("height_field", vertices.data(), static_cast<int>(vertices.size() / 3),
                                      triangles.data(), static_cast<int>(triangles.size() / 3));
  e->input.rows = rows, e->input.columns = columns;
  e->input.spacing[0] = spacing[0], e->input.spacing[1] = spacing[1];
  e->input.heights.assign(heights, heights + size_t(rows) * size_t(columns));
  e->view.type = spu::ShapeType::height_field;
  return push_surface(std::move(e));
}

uint32_t ShapeDictionary::push_surface(std::unique_ptr<Entry> e) {
  e->view.mesh = e->surface.view();
  e->input.dropped_triangles = e->surface.dropped_triangles;
  e->input.num_triangles = e->view.mesh.num_triangles;
  for (int k = 0; k < 3; ++k) e->lo[k] = e->surface.lo[k], e->hi[k] = e->surface.hi[k];
  e->bytes = e->surface.bytes();
  return push(std::move(e));
}

uint32_t ShapeDictionary::add_compound(const CompoundPart* parts, int count, CompoundInfo* info, bool recentre) {
  if (!parts || count < 1 || count > kMaxCompoundParts)
    throw ShapeError("compound: needs 1 to " + std::to_string(kMaxCompoundParts) + " parts, got " + std::to_string(count));
  auto e = std::make_unique<Entry>();
  e->parts.assign(parts, parts + count);
  for (int i = 0; i < count; ++i) {
    CompoundPart& p = e->parts[i];
    const std::string who = "compound: part " + std::to_string(i);
    if (p.shape >= entries_.size())
      throw ShapeError(who + ": shape " + std::to_string(p.shape) + " does not exist (the dictionary has " +
                       std::to_string(entries_.size()) + ")");
    const spu::ShapeType t = entries_[p.shape]->view.type;
    if (!spu::is_convex(t))
      throw ShapeError(who + ": a " + std::string(spu::shape_type_name(t)) +
                       " cannot be a part (parts are spheres, capsules, boxes or hulls)");
    for (float x : p.position)
      if (!std::isfinite(x)) throw ShapeError(who + ": position is not finite");
    double q2 = 0;
    for (float x : p.orientation) {
      if (!std::isfinite(x)) throw ShapeError(who + ": orientation is not finite");
      q2 += double(x) * x;
    }
    if (!(q2 > 1e-12)) throw ShapeError(who + ": orientation is zero");
    // A unit quaternion to float rounding is kept as it is, so a stored part rebuilds bit for bit.
    if (std::fabs(q2 - 1.0) > 1e-6)
      for (float& x : p.orientation) x = float(x / std::sqrt(q2));
    require_positive("compound part", "scale", p.scale);
  }
  e->view.type = spu::ShapeType::compound;
  const auto link = [&]() {
    e->part_views.resize(e->parts.size());
    for (size_t i = 0; i < e->parts.size(); ++i) {
      spu::CompoundPartView& v = e->part_views[i];
      const CompoundPart& p = e->parts[i];
      v.shape = &entries_[p.shape]->view;
      std::copy(p.position, p.position + 3, v.position);
      std::copy(p.orientation, p.orientation + 4, v.orientation);
      v.scale = p.scale;
    }
    e->view.compound.num_parts = count;
    e->view.compound.parts = e->part_views.data();
  };
  link();
  const MassProperties m = mass_properties_from_density(e->view, 1.0f, 1.0f);
  CompoundInfo ci;
  if (recentre) {
    for (CompoundPart& p : e->parts)
      for (int k = 0; k < 3; ++k) p.position[k] = float(double(p.position[k]) - m.center_of_mass[k]);
    for (int k = 0; k < 3; ++k) ci.shift[k] = float(m.center_of_mass[k]);
    link();
  }
  e->bytes = e->parts.size() * sizeof(CompoundPart);
  const uint32_t index = push(std::move(e));
  if (info) *info = ci;
  return index;
}

const std::vector<CompoundPart>& ShapeDictionary::compound_parts(uint32_t index) const {
  const Entry& e = entry(index);
  if (e.view.type != spu::ShapeType::compound)
    throw ShapeError("shape " + std::to_string(index) + " is a " + spu::shape_type_name(e.view.type) + ", not a compound");
  return e.parts;
}

const ShapeDictionary::Entry& ShapeDictionary::entry(uint32_t index) const {
  if (index >= entries_.size())
    throw std::out_of_range("shape " + std::to_string(index) + " does not exist (the dictionary has " +
                            std::to_string(entries_.size()) + ")");
  return *entries_[index];
}

spu::ShapeType ShapeDictionary::type(uint32_t index) const { return entry(index).view.type; }
const spu::ShapeView& ShapeDictionary::view(uint32_t index) const { return entry(index).view; }
bool ShapeDictionary::is_static_infinite(uint32_t index) const { return type(index) == spu::ShapeType::plane; }
bool ShapeDictionary::is_static_only(uint32_t index) const {
  const spu::ShapeType t = type(index);
  return t == spu::ShapeType::plane || spu::is_triangle_surface(t);
}

const SurfaceInput& ShapeDictionary::surface_input(uint32_t index) const {
  const Entry& e = entry(index);
  if (!spu::is_triangle_surface(e.view.type))
    throw ShapeError("shape " + std::to_string(index) + " is a " + spu::shape_type_name(e.view.type) +
                     ", not a mesh or a height field");
  return e.input;
}
size_t ShapeDictionary::bytes(uint32_t index) const { return entry(index).bytes; }

const HullInfo& ShapeDictionary::hull_info(uint32_t index) const {
  const Entry& e = entry(index);
  if (e.view.type != spu::ShapeType::hull)
    throw ShapeError("shape " + std::to_string(index) + " is a " + spu::shape_type_name(e.view.type) + ", not a hull");
  return e.info;
}

void ShapeDictionary::local_aabb(uint32_t index, float scale, float min[3], float max[3]) const {
  const Entry& e = entry(index);
  const spu::ShapeView& v = e.view;
  if (v.type == spu::ShapeType::plane) return plane_box(v, min, max);
  if (v.type == spu::ShapeType::compound) {
    spu::Pose at;
    at.scale = scale;
    return world_aabb(index, at, min, max);
  }
  require_positive(spu::shape_type_name(v.type), "scale", scale);
  const double s = scale;
  double lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    double h = 0;
    switch (v.type) {
      case spu::ShapeType::sphere: h = v.radius; break;
      case spu::ShapeType::capsule: h = v.radius + (k == 2 ? v.half_height : 0.0f); break;
      case spu::ShapeType::box: h = v.half_extents[k]; break;
      default: break;
    }
    const bool boxed = v.type == spu::ShapeType::hull || spu::is_triangle_surface(v.type);  // boxes kept at unit scale
    lo[k] = boxed ? e.lo[k] * s : -h * s;
    hi[k] = boxed ? e.hi[k] * s : h * s;
  }
  store(lo, hi, min, max);
}

void ShapeDictionary::world_aabb(uint32_t index, const spu::Pose& pose, float min[3], float max[3]) const {
  const Entry& e = entry(index);
  const spu::ShapeView& v = e.view;
  if (v.type == spu::ShapeType::plane) return plane_box(v, min, max);
  require_positive(spu::shape_type_name(v.type), "pose scale", pose.scale);
  if (v.type == spu::ShapeType::compound) {  // the parts' boxes together
    for (int k = 0; k < 3; ++k) min[k] = std::numeric_limits<float>::infinity(), max[k] = -min[k];
    for (size_t i = 0; i < e.parts.size(); ++i) {
      float lo[3], hi[3];
      world_aabb(e.parts[i].shape, spu::part_pose(pose, e.part_views[i]), lo, hi);
      for (int k = 0; k < 3; ++k) min[k] = std::min(min[k], lo[k]), max[k] = std::max(max[k], hi[k]);
    }
    return;
  }
  const Mat3d R = rotation(pose.orientation);
  const double s = pose.scale;
  double lo[3], hi[3];
  if (v.type == spu::ShapeType::hull) {
    for (int k = 0; k < 3; ++k) lo[k] = kInf, hi[k] = -kInf;
    const float* p = e.hull.vertices.data();
    for (int i = 0; i < e.hull.num_vertices(); ++i, p += 3) {
      const Vec3d w = mul(R, Vec3d::load(p)) * s;
      for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], w[k]), hi[k] = std::max(hi[k], w[k]);
    }
  } else if (spu::is_triangle_surface(v.type)) {  // its box at unit scale, turned (a surface's vertices may be many)
    const Vec3d c = (Vec3d::load(e.lo) + Vec3d::load(e.hi)) * 0.5, h = (Vec3d::load(e.hi) - Vec3d::load(e.lo)) * 0.5;
    const Vec3d wc = mul(R, c) * s;
    for (int k = 0; k < 3; ++k) {
      const double r = (std::fabs(R.m[k][0]) * h.x + std::fabs(R.m[k][1]) * h.y + std::fabs(R.m[k][2]) * h.z) * s;
      lo[k] = wc[k] - r, hi[k] = wc[k] + r;
    }
  } else {
    for (int k = 0; k < 3; ++k) {
      double h = 0;  // half extent of the rotated shape along world axis k
      if (v.type == spu::ShapeType::sphere) h = v.radius;
      if (v.type == spu::ShapeType::capsule) h = v.radius + std::fabs(R.m[k][2]) * v.half_height;
      if (v.type == spu::ShapeType::box)
        h = std::fabs(R.m[k][0]) * v.half_extents[0] + std::fabs(R.m[k][1]) * v.half_extents[1] +
            std::fabs(R.m[k][2]) * v.half_extents[2];
      lo[k] = -h * s, hi[k] = h * s;
    }
  }
  for (int k = 0; k < 3; ++k) lo[k] += pose.position[k], hi[k] += pose.position[k];
  store(lo, hi, min, max);
}

}  // namespace cellphys::ppe

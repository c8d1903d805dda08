#include "runtime/ppe/mass_properties.h"

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "runtime/base/vec3.h"

namespace cellphys::ppe {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

[[noreturn]] void fail(spu::ShapeType t, const std::string& what) {
  throw ShapeError(std::string(spu::shape_type_name(t)) + " mass properties: " + what);
}

void require_positive(spu::ShapeType t, const char* what, double v) {
  if (!(v > 0.0) || !std::isfinite(v)) fail(t, std::string(what) + " must be positive and finite, got " + num(v));
}

MassProperties scaled(const spu::ShapeView& s, double scale, double density);

// The parts at their poses, unit density: volumes add, centroids average, each part's inertia
// turns with it and moves to the common centroid (parallel axes). Where parts overlap, the
// overlap counts twice: a compound's parts are taken as solids side by side.
MassProperties compound_mass_properties(const spu::CompoundView& c) {
  if (c.num_parts < 1 || !c.parts) fail(spu::ShapeType::compound, "no parts");
  double V = 0;
  Vec3d S{0, 0, 0};
  struct Part {
    MassProperties m;
    Vec3d centre;
    double R[3][3];
  };
  std::vector<Part> parts(size_t(c.num_parts));
  for (int i = 0; i < c.num_parts; ++i) {
    const spu::CompoundPartView& p = c.parts[i];
    Part& q = parts[i];
    q.m = scaled(*p.shape, p.scale, 1.0);
    const double w = p.orientation[0], x = p.orientation[1], y = p.orientation[2], z = p.orientation[3];
    const double R[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
                            {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
                            {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}};
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) q.R[j][k] = R[j][k];
    Vec3d local{q.m.center_of_mass[0], q.m.center_of_mass[1], q.m.center_of_mass[2]};
    q.centre = Vec3d::load(p.position) + Vec3d{dot(Vec3d{R[0][0], R[0][1], R[0][2]}, local),
                                              dot(Vec3d{R[1][0], R[1][1], R[1][2]}, local),
                                              dot(Vec3d{R[2][0], R[2][1], R[2][2]}, local)};
    V += q.m.volume;
    S = S + q.centre * q.m.volume;
  }
  MassProperties m;
  m.volume = m.mass = V;
  const Vec3d g = S * (1.0 / V);
  for (int k = 0; k < 3; ++k) m.center_of_mass[k] = g[k];
  double T[3][3] = {};
  for (const Part& q : parts) {
    const double* I = q.m.inertia;
    const double L[3][3] = {{I[0], I[3], I[4]}, {I[3], I[1], I[5]}, {I[4], I[5], I[2]}};
    const Vec3d d = q.centre - g;
    const double dd = dot(d, d);
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) {
        double r = 0;  // (R L R^T)_jk
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) r += q.R[j][a] * L[a][b] * q.R[k][b];
        T[j][k] += r + q.m.volume * ((j == k ? dd : 0.0) - d[j] * d[k]);
      }
  }
  m.inertia[0] = T[0][0], m.inertia[1] = T[1][1], m.inertia[2] = T[2][2];
  m.inertia[3] = T[0][1], m.inertia[4] = T[0][2], m.inertia[5] = T[1][2];
  return m;
}

// Unit density and unit scale.
MassProperties unit(const spu::ShapeView& s) {
  MassProperties m;
  double* I = m.inertia;
  switch (s.type) {
    case spu::ShapeType::sphere: {
      const double r = s.radius;
      require_positive(s.type, "radius", r);
      m.volume = 4.0 / 3.0 * kPi * r * r * r;
      I[0] = I[1] = I[2] = 0.4 * m.volume * r * r;
      break;
    }
    case spu::ShapeType::capsule: {
      // Cylinder of length 2h plus two hemispheres. A hemisphere's moment about a transverse
      // axis through its flat face is 2/5 m r^2; moving to its own centroid (3r/8 from the
      // face) and then to the capsule centre (h + 3r/8) gives, for both together,
      // m_s (2/5 r^2 + h^2 + 3/4 h r).
      const double r = s.radius, h = s.half_height;
      require_positive(s.type, "radius", r);
      if (!(h >= 0.0) || !std::isfinite(h)) fail(s.type, "half height must be >= 0 and finite, got " + num(h));
      const double vc = 2.0 * kPi * r * r * h, vs = 4.0 / 3.0 * kPi * r * r * r;
      m.volume = vc + vs;
      I[0] = I[1] = vc * (r * r / 4.0 + h * h / 3.0) + vs * (0.4 * r * r + h * h + 0.75 * h * r);
      I[2] = vc * r * r / 2.0 + vs * 0.4 * r * r;
      break;
    }
    case spu::ShapeType::box: {
      const double a = s.half_extents[0], b = s.half_extents[1], c = s.half_extents[2];
      require_positive(s.type, "half extent x", a);
      require_positive(s.type, "half extent y", b);
      require_positive(s.type, "half extent z", c);
      m.volume = 8.0 * a * b * c;
      I[0] = m.volume / 3.0 * (b * b + c * c);
      I[1] = m.volume / 3.0 * (a * a + c * c);
      I[2] = m.volume / 3.0 * (a * a + b * b);
      break;
    }
    case spu::ShapeType::hull: m = polyhedron_mass_properties(s.hull); break;
    case spu::ShapeType::plane: fail(s.type, "a static plane has no mass, volume or inertia");
    case spu::ShapeType::mesh:
    case spu::ShapeType::height_field:
      fail(s.type, "a triangle surface is static level geometry: it has no mass, volume or inertia");
    case spu::ShapeType::compound: m = compound_mass_properties(s.compound); break;
  }
  if (!(m.volume > 0.0) || !std::isfinite(m.volume)) fail(s.type, "the shape has no positive, finite volume");
  return m;
}

MassProperties scaled(const spu::ShapeView& s, double scale, double density) {
  MassProperties m = unit(s);
  const double s3 = scale * scale * scale, s5 = s3 * scale * scale;
  m.volume *= s3;
  m.mass = density * m.volume;
  for (double& c : m.center_of_mass) c *= scale;
  for (double& i : m.inertia) i *= density * s5;
  if (!std::isfinite(m.mass) || !(m.mass > 0.0)) fail(s.type, "mass " + num(m.mass) + " is not positive and finite");
  for (double i : m.inertia)
    if (!std::isfinite(i)) fail(s.type, "inertia is not finite (scale or density too large)");
  return m;
}

}  // namespace

MassProperties polyhedron_mass_properties(const spu::HullView& h) {
  if (h.num_vertices < 4 || h.num_faces < 4 || !h.vertices || !h.face_start || !h.face_vertices)
    fail(spu::ShapeType::hull, "not a closed polyhedron");
  auto vtx = [&](int i) { return Vec3d::load(h.vertices + 3 * i); };
  Vec3d ref{};  // integrate about the vertex mean: smaller terms, less cancellation
  for (int i = 0; i < h.num_vertices; ++i) ref = ref + vtx(i);
  ref = ref / h.num_vertices;

  // Each face fanned into triangles, each triangle with ref a tetrahedron: volume det/6,
  // first moment det/24 (a+b+c), second moments det/120 (aa' + bb' + cc' + ss'), s = a+b+c.
  double V = 0, C[3][3] = {};
  Vec3d S{};
  for (int f = 0; f < h.num_faces; ++f) {
    const int s = h.face_start[f], e = h.face_start[f + 1];
    const Vec3d a = vtx(h.face_vertices[s]) - ref;
    for (int i = s + 1; i + 1 < e; ++i) {
      const Vec3d b = vtx(h.face_vertices[i]) - ref, c = vtx(h.face_vertices[i + 1]) - ref;
      const double det = dot(a, cross(b, c));
      const Vec3d sum = a + b + c;
      V += det / 6.0;
      S = S + sum * (det / 24.0);
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) C[j][k] += det / 120.0 * (a[j] * a[k] + b[j] * b[k] + c[j] * c[k] + sum[j] * sum[k]);
    }
  }
  MassProperties m;
  m.volume = m.mass = V;
  if (!(V > 0.0) || !std::isfinite(V)) return m;  // callers report the missing volume
  const Vec3d g = S / V;
  for (int k = 0; k < 3; ++k) m.center_of_mass[k] = ref[k] + g[k];
  for (int j = 0; j < 3; ++j)
    for (int k = 0; k < 3; ++k) C[j][k] -= V * g[j] * g[k];  // parallel axis to the centroid
  m.inertia[0] = C[1][1] + C[2][2];
  m.inertia[1] = C[0][0] + C[2][2];
  m.inertia[2] = C[0][0] + C[1][1];
  m.inertia[3] = -C[0][1];
  m.inertia[4] = -C[0][2];
  m.inertia[5] = -C[1][2];
  return m;
}

MassProperties mass_properties_from_density(const spu::ShapeView& shape, float scale, float density) {
  if (shape.type == spu::ShapeType::plane || spu::is_triangle_surface(shape.type)) unit(shape);  // throws: static-only shapes first, whatever else is wrong
  require_positive(shape.type, "scale", scale);
  require_positive(shape.type, "density", density);
  return scaled(shape, scale, density);
}

MassProperties mass_properties_from_mass(const spu::ShapeView& shape, float scale, float mass) {
  if (shape.type == spu::ShapeType::plane || spu::is_triangle_surface(shape.type)) unit(shape);
  require_positive(shape.type, "scale", scale);
  require_positive(shape.type, "mass", mass);
  MassProperties m = scaled(shape, scale, 1.0);
  const double density = mass / m.volume;
  m.mass = mass;
  for (double& i : m.inertia) i *= density;
  return m;
}

MassProperties mass_properties_from_density(const ShapeDictionary& shapes, uint32_t shape, float scale,
                                            float density) {
  return mass_properties_from_density(shapes.view(shape), scale, density);
}

MassProperties mass_properties_from_mass(const ShapeDictionary& shapes, uint32_t shape, float scale, float mass) {
  return mass_properties_from_mass(shapes.view(shape), scale, mass);
}

}  // namespace cellphys::ppe

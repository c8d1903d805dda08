// Shared by the peers: mass properties and hull geometry from a cellphys world built from the
// scene, the forces the bench applies itself, quaternion helpers, and the engine dispatch.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "bench/peers/peer.h"

namespace cellphys::bench {

void quat_rotate(const double q[4], const double v[3], double out[3]) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  const double tx = 2 * (y * v[2] - z * v[1]), ty = 2 * (z * v[0] - x * v[2]), tz = 2 * (x * v[1] - y * v[0]);
  out[0] = v[0] + w * tx + (y * tz - z * ty);
  out[1] = v[1] + w * ty + (z * tx - x * tz);
  out[2] = v[2] + w * tz + (x * ty - y * tx);
}

void quat_rotate_inv(const double q[4], const double v[3], double out[3]) {
  const double c[4] = {q[0], -q[1], -q[2], -q[3]};
  quat_rotate(c, v, out);
}

void world_inertia_mul(const double q[4], const double I[6], const double w[3], double out[3]) {
  double b[3], ib[3];
  quat_rotate_inv(q, w, b);
  ib[0] = I[0] * b[0] + I[3] * b[1] + I[4] * b[2];
  ib[1] = I[3] * b[0] + I[1] * b[1] + I[5] * b[2];
  ib[2] = I[4] * b[0] + I[5] * b[1] + I[2] * b[2];
  quat_rotate(q, ib, out);
}

int body_index(const scene::SceneDesc& scene, const std::string& id) {
  if (id == scene::kWorld) return -1;
  for (size_t i = 0; i < scene.bodies.size(); ++i)
    if (scene.bodies[i].id == id) return static_cast<int>(i);
  throw std::invalid_argument("no body '" + id + "'");
}

bool is_joint_type(const std::string& t) {
  return t == "point_to_point" || t == "hinge" || t == "slider" || t == "fixed" || t == "distance" ||
         t == "cone_twist";
}

namespace {
double jparam(const ppe::ForceParams& p, const char* name, int k = 0) {
  for (const auto& [n, v] : p)
    if (n == name && static_cast<int>(v.size()) > k) return v[k];
  return 0.0;
}
void vec_of(const ppe::ForceParams& p, const char* name, double out[3]) {
  for (int k = 0; k < 3; ++k) out[k] = jparam(p, name, k);
}
double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
void cross3(const double a[3], const double b[3], double o[3]) {
  o[0] = a[1] * b[2] - a[2] * b[1], o[1] = a[2] * b[0] - a[0] * b[2], o[2] = a[0] * b[1] - a[1] * b[0];
}
bool normalise(double v[3]) {
  const double n = std::sqrt(dot3(v, v));
  if (n < 1e-12) return false;
  for (int k = 0; k < 3; ++k) v[k] /= n;
  return true;
}
// ref made perpendicular to the unit axis; any perpendicular when ref is zero or along the axis.
void perpendicular(const double axis[3], double ref[3]) {
  const double d = dot3(ref, axis);
  for (int k = 0; k < 3; ++k) ref[k] -= d * axis[k];
  if (normalise(ref)) return;
  const double e[3] = {std::fabs(axis[0]) < 0.9 ? 1.0 : 0.0, std::fabs(axis[0]) < 0.9 ? 0.0 : 1.0, 0.0};
  cross3(axis, e, ref);
  normalise(ref);
}
void body_pose(const scene::BodySpec& b, double p[3], double q[4]) {
  for (int k = 0; k < 3; ++k) p[k] = b.state.position[k];
  double n = 0;
  for (int k = 0; k < 4; ++k) q[k] = b.state.orientation[k], n += q[k] * q[k];
  n = std::sqrt(n);
  for (int k = 0; k < 4; ++k) q[k] /= n;
}
}  // namespace

std::vector<JointSpec> scene_joints(const scene::SceneDesc& scene) {
  std::vector<JointSpec> out;
  for (size_t f = 0; f < scene.forces.size(); ++f) {
    const scene::ForceSpec& fs = scene.forces[f];
    if (!is_joint_type(fs.type)) continue;
    const ppe::ForceParams& P = fs.params;
    JointSpec j;
    j.type = fs.type;
    j.force = f;
    j.a = body_index(scene, fs.a);
    j.b = body_index(scene, fs.b);
    if (scene.bodies[j.a].is_static) throw Unsupported("a joint whose body a is static ('" + fs.a + "')");
    vec_of(P, "point_a", j.pa);
    vec_of(P, "point_b", j.pb);
    vec_of(P, "axis_a", j.axis_a);
    vec_of(P, "axis_b", j.axis_b);
    vec_of(P, "ref_a", j.ref_a);
    vec_of(P, "ref_b", j.ref_b);
    j.has_axis = normalise(j.axis_a) && normalise(j.axis_b);
    if (!j.has_axis) j.axis_a[0] = j.axis_a[1] = 0, j.axis_a[2] = 1, j.axis_b[0] = j.axis_b[1] = 0, j.axis_b[2] = 1;
    perpendicular(j.axis_a, j.ref_a);
    perpendicular(j.axis_b, j.ref_b);
    j.lower = jparam(P, "lower");
    j.upper = jparam(P, "upper");
    j.motor_speed = jparam(P, "motor_speed");
    j.motor_max = fs.type == "slider" ? jparam(P, "motor_force") : jparam(P, "motor_torque");
    j.spring_k = jparam(P, "spring_stiffness");
    j.spring_c = jparam(P, "spring_damping");
    j.spring_rest = fs.type == "hinge" ? jparam(P, "spring_angle") : fs.type == "slider" ? jparam(P, "spring_travel")
                                                                                       : jparam(P, "rest_length");
    j.min_length = jparam(P, "min_length");
    j.max_length = jparam(P, "max_length");
    j.cone_angle = jparam(P, "cone_angle");
    j.twist_lower = jparam(P, "twist_lower");
    j.twist_upper = jparam(P, "twist_upper");
    // A static body b becomes the world: its point and directions in world coordinates.
    if (j.b >= 0 && scene.bodies[j.b].is_static) {
      double p[3], q[4], t[3];
      body_pose(scene.bodies[j.b], p, q);
      quat_rotate(q, j.pb, t);
      for (int k = 0; k < 3; ++k) j.pb[k] = p[k] + t[k];
      quat_rotate(q, j.axis_b, t);
      std::copy(t, t + 3, j.axis_b);
      quat_rotate(q, j.ref_b, t);
      std::copy(t, t + 3, j.ref_b);
      j.b = -1;
    }
    double p[3], q[4];
    body_pose(scene.bodies[j.a], p, q);
    quat_rotate(q, j.pa, j.wpa);
    for (int k = 0; k < 3; ++k) j.wpa[k] += p[k];
    quat_rotate(q, j.axis_a, j.wna);
    quat_rotate(q, j.ref_a, j.wua);
    if (j.b >= 0) {
      body_pose(scene.bodies[j.b], p, q);
      quat_rotate(q, j.pb, j.wpb);
      for (int k = 0; k < 3; ++k) j.wpb[k] += p[k];
      quat_rotate(q, j.axis_b, j.wnb);
      quat_rotate(q, j.ref_b, j.wub);
    } else {
      std::copy(j.pb, j.pb + 3, j.wpb);
      std::copy(j.axis_b, j.axis_b + 3, j.wnb);
      std::copy(j.ref_b, j.ref_b + 3, j.wub);
    }
    double d[3], c[3];
    for (int k = 0; k < 3; ++k) d[k] = j.wpb[k] - j.wpa[k];
    j.travel0 = dot3(d, j.wna);
    j.length0 = std::sqrt(dot3(d, d));
    // The twist of a cone_twist is measured with ref_b turned back by the swing; at a start
    // with the axes aligned, as scenes place their joints, that is the hinge's angle.
    cross3(j.wua, j.wub, c);
    j.angle0 = std::atan2(dot3(c, j.wna), dot3(j.wua, j.wub));
    out.push_back(j);
  }
  return out;
}

namespace {
// A hull's vertices, planes and faces (each counter-clockwise seen from outside) at a scale.
void hull_geometry(const spu::HullView& h, double s, std::vector<double>& vertices, std::vector<double>& planes,
                   std::vector<int>& faces) {
  for (int k = 0; k < 3 * h.num_vertices; ++k) vertices.push_back(s * h.vertices[k]);
  for (int f = 0; f < h.num_faces; ++f) {
    const float* pl = h.planes + 4 * f;
    planes.insert(planes.end(), {pl[0], pl[1], pl[2], s * pl[3]});
    const int b0 = h.face_start[f], b1 = h.face_start[f + 1];
    std::vector<int> loop(h.face_vertices + b0, h.face_vertices + b1);
    // Make the loop counter-clockwise seen from outside (its normal along the plane's).
    double n[3] = {};
    for (size_t k = 0; k < loop.size(); ++k) {
      const float* p = h.vertices + 3 * loop[k];
      const float* q = h.vertices + 3 * loop[(k + 1) % loop.size()];
      n[0] += (p[1] - q[1]) * (p[2] + q[2]);
      n[1] += (p[2] - q[2]) * (p[0] + q[0]);
      n[2] += (p[0] - q[0]) * (p[1] + q[1]);
    }
    if (n[0] * pl[0] + n[1] * pl[1] + n[2] * pl[2] < 0) std::reverse(loop.begin(), loop.end());
    faces.push_back(static_cast<int>(loop.size()));
    faces.insert(faces.end(), loop.begin(), loop.end());
  }
}
}  // namespace

std::vector<BodyInfo> body_info(const scene::SceneDesc& scene) {
  scene::SceneDesc copy = scene;
  copy.forces.clear();  // mass properties only
  const scene::BuiltScene built = scene::build_world(copy);
  const ppe::World& w = *built.world;
  std::vector<BodyInfo> out(scene.bodies.size());
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const scene::BodySpec& b = scene.bodies[i];
    BodyInfo& o = out[i];
    for (size_t s = 0; s < scene.shapes.size(); ++s)
      if (scene.shapes[s].name == b.shape) o.shape = static_cast<int>(s);
    const scene::ShapeSpec& spec = scene.shapes[o.shape];
    if (!w.is_static(built.bodies[i])) {
      o.mass = w.mass(built.bodies[i]);
      const float* I = w.inertia_body(built.bodies[i]);
      for (int k = 0; k < 6; ++k) o.inertia[k] = I[k];
    }
    // The dictionary holds shapes in file order (build_world adds them so, to a fresh world).
    if (spec.type != spu::ShapeType::hull && spec.type != spu::ShapeType::mesh &&
        spec.type != spu::ShapeType::height_field && spec.type != spu::ShapeType::compound)
      continue;
    const spu::ShapeView& v = w.shapes().view(static_cast<uint32_t>(o.shape));
    if (v.type != spec.type) throw std::logic_error("shape order mismatch");
    const double s = b.scale;
    if (spec.type == spu::ShapeType::hull) hull_geometry(v.hull, s, o.hull_vertices, o.hull_planes, o.hull_faces);
    if (spec.type == spu::ShapeType::mesh || spec.type == spu::ShapeType::height_field) {
      for (int k = 0; k < 3 * v.mesh.num_vertices; ++k) o.mesh_vertices.push_back(s * v.mesh.vertices[k]);
      o.mesh_triangles.assign(v.mesh.triangles, v.mesh.triangles + 3 * v.mesh.num_triangles);
    }
    if (spec.type == spu::ShapeType::compound) {
      for (const ppe::CompoundPart& cp : w.shapes().compound_parts(static_cast<uint32_t>(o.shape))) {
        BodyInfo::Part part;
        part.shape = static_cast<int>(cp.shape);
        for (int k = 0; k < 3; ++k) part.position[k] = s * cp.position[k];
        for (int k = 0; k < 4; ++k) part.orientation[k] = cp.orientation[k];
        part.scale = s * cp.scale;
        const spu::ShapeView& pv = w.shapes().view(cp.shape);
        if (pv.type == spu::ShapeType::hull)
          hull_geometry(pv.hull, part.scale, part.hull_vertices, part.hull_planes, part.hull_faces);
        o.parts.push_back(std::move(part));
      }
    }
  }
  return out;
}

namespace {
double param(const ppe::ForceParams& p, const char* name, int k = 0) {
  for (const auto& [n, v] : p)
    if (n == name && static_cast<int>(v.size()) > k) return v[k];
  return 0.0;
}
}  // namespace

ExternalForces::ExternalForces(const scene::SceneDesc& scene, const std::vector<BodyInfo>& info, bool springs)
    : info_(info) {
  for (const scene::ForceSpec& f : scene.forces) {
    Term t;
    t.a = body_index(scene, f.a);
    t.b = f.type == "spring" ? body_index(scene, f.b) : -1;
    for (int k = 0; k < 3; ++k) {
      t.pa[k] = param(f.params, "point_a", k);
      t.pb[k] = param(f.params, "point_b", k);
    }
    if (f.type == "spring") {
      if (!springs) continue;
      t.kind = 0;
      t.k = param(f.params, "stiffness");
      t.c = param(f.params, "damping");
      t.rest = param(f.params, "rest_length");
    } else if (f.type == "applied_wrench") {
      t.kind = 1;
      for (int k = 0; k < 3; ++k) t.f[k] = param(f.params, "force_world", k), t.t[k] = param(f.params, "torque_world", k);
    } else if (f.type == "damping") {
      t.kind = 2;
      t.k = param(f.params, "linear");
      t.c = param(f.params, "angular");
    } else {
      continue;  // the joints: the peers' own; gyroscopic: native; anything else is refused by the peer
    }
    terms_.push_back(t);
  }
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const scene::BodySpec& b = scene.bodies[i];
    if (b.is_static || (b.linear_damping == 0 && b.angular_damping == 0)) continue;
    Term t;
    t.kind = 2;
    t.a = static_cast<int>(i);
    t.k = b.linear_damping;
    t.c = b.angular_damping;
    terms_.push_back(t);
  }
}

void ExternalForces::evaluate(const std::vector<State>& s, std::vector<double>& out) const {
  out.assign(6 * s.size(), 0.0);
  for (const Term& t : terms_) {
    const State& A = s[t.a];
    double* fa = &out[6 * t.a];
    if (t.kind == 0) {
      double ra[3], xa[3], va[3], xb[3], vb[3] = {0, 0, 0}, rb[3] = {0, 0, 0};
      quat_rotate(A.q, t.pa, ra);
      for (int k = 0; k < 3; ++k) xa[k] = A.p[k] + ra[k];
      va[0] = A.v[0] + A.w[1] * ra[2] - A.w[2] * ra[1];
      va[1] = A.v[1] + A.w[2] * ra[0] - A.w[0] * ra[2];
      va[2] = A.v[2] + A.w[0] * ra[1] - A.w[1] * ra[0];
      if (t.b >= 0) {
        const State& B = s[t.b];
        quat_rotate(B.q, t.pb, rb);
        for (int k = 0; k < 3; ++k) xb[k] = B.p[k] + rb[k];
        vb[0] = B.v[0] + B.w[1] * rb[2] - B.w[2] * rb[1];
        vb[1] = B.v[1] + B.w[2] * rb[0] - B.w[0] * rb[2];
        vb[2] = B.v[2] + B.w[0] * rb[1] - B.w[1] * rb[0];
      } else {
        for (int k = 0; k < 3; ++k) xb[k] = t.pb[k];
      }
      double d[3], len = 0;
      for (int k = 0; k < 3; ++k) d[k] = xa[k] - xb[k], len += d[k] * d[k];
      len = std::sqrt(len);
      if (len < 1e-12) continue;
      double n[3], speed = 0;
      for (int k = 0; k < 3; ++k) n[k] = d[k] / len, speed += (va[k] - vb[k]) * n[k];
      const double mag = t.k * (len - t.rest) + t.c * speed;
      double f[3];
      for (int k = 0; k < 3; ++k) f[k] = -mag * n[k];
      auto add = [&](double* o, const double* r, double sign) {
        for (int k = 0; k < 3; ++k) o[k] += sign * f[k];
        o[3] += sign * (r[1] * f[2] - r[2] * f[1]);
        o[4] += sign * (r[2] * f[0] - r[0] * f[2]);
        o[5] += sign * (r[0] * f[1] - r[1] * f[0]);
      };
      add(fa, ra, 1.0);
      if (t.b >= 0) add(&out[6 * t.b], rb, -1.0);
    } else if (t.kind == 1) {
      for (int k = 0; k < 3; ++k) fa[k] += t.f[k], fa[3 + k] += t.t[k];
    } else {
      const BodyInfo& bi = info_[t.a];
      double Iw[3];
      world_inertia_mul(A.q, bi.inertia, A.w, Iw);
      for (int k = 0; k < 3; ++k) fa[k] -= t.k * bi.mass * A.v[k], fa[3 + k] -= t.c * Iw[k];
    }
  }
}

std::unique_ptr<Peer> make_peer(const scene::SceneDesc& scene, const EngineConfig& c) {
  if (c.engine == "cellphys") return make_cellphys(scene, c);
  if (c.engine == "bullet") return make_bullet(scene, c);
  if (c.engine == "ode") return make_ode(scene, c);
  if (c.engine == "mujoco") return make_mujoco(scene, c);
  throw std::invalid_argument("unknown engine '" + c.engine + "' (cellphys, bullet, ode, mujoco)");
}

}  // namespace cellphys::bench

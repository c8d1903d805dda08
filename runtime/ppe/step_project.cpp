#include "runtime/ppe/step_project.h"

#include <cmath>
#include <cstring>

#include "runtime/base/mat3.h"
#include "runtime/base/quat.h"
#include "runtime/base/vec3.h"
#include "cellphys/gen/force_table.h"

namespace cellphys::ppe {

namespace {

// The byte offsets of a force type's two held points in its instance, or -1 (no such points).
struct HeldPoints {
  int32_t a = -1, b = -1;
};

HeldPoints held_points(gen::ForceType t) {
  const gen::ForceInfo& info = gen::kForceTable[static_cast<size_t>(t)];
  return {info.held_a, info.held_b};
}

Vec3d read_vec3(const std::vector<unsigned char>& inst, int32_t at) {
  float v[3];
  std::memcpy(v, inst.data() + at, sizeof v);
  return Vec3d::load(v);
}

// Where a body's frame puts a point, and what moving it costs: a body that does not move (static,
// asleep, the world) has no inverse mass or inertia.
struct Side {
  bool moves = false;
  Vec3d x{}, r{};  // centre, and the point from it (world)
  double w = 0;
  Mat3d Iinv{};
};

Side side(const std::vector<WorldBody>& bodies, uint32_t id, const Vec3d& local) {
  Side s;
  if (id == kWorldBody) {
    s.x = local;  // a world point
    return s;
  }
  const WorldBody& b = bodies[id];
  const Mat3d R = quat_to_matrix(Quatd::load(b.state.orientation));
  s.x = Vec3d::load(b.state.position);
  s.r = mul(R, local);
  s.moves = !b.is_static && b.awake;
  if (s.moves) {
    s.w = 1.0 / b.mass;
    s.Iinv = rotate_sym(R, b.inverse_inertia);
  }
  return s;
}

// dp at the point of a body moved by the correction P (the body's share): w P + (I^-1 (r x P)) x r.
Vec3d point_moves(const Side& s, const Vec3d& P) { return P * s.w + cross(mul(s.Iinv, cross(s.r, P)), s.r); }

void move(WorldBody& b, const Side& s, const Vec3d& P) {
  const Vec3d dx = P * s.w, dtheta = mul(s.Iinv, cross(s.r, P));
  const Vec3d x = Vec3d::load(b.state.position) + dx;
  b.state.position[0] = float(x.x), b.state.position[1] = float(x.y), b.state.position[2] = float(x.z);
  const Quatd q = quat_normalized(quat_mul(quat_exp(dtheta), Quatd::load(b.state.orientation)));
  b.state.orientation[0] = float(q.w), b.state.orientation[1] = float(q.x), b.state.orientation[2] = float(q.y),
  b.state.orientation[3] = float(q.z);
}

// x with K x = c for a symmetric positive definite K given by its columns; false if singular.
bool solve3(const Vec3d col[3], const Vec3d& c, Vec3d& x) {
  const double det = dot(col[0], cross(col[1], col[2]));
  if (!(std::fabs(det) > 1e-300)) return false;
  x = Vec3d{dot(c, cross(col[1], col[2])), dot(col[0], cross(c, col[2])), dot(col[0], cross(col[1], c))} * (1.0 / det);
  return true;
}

}  // namespace

void project_joints(const WorldSettings& s, const std::vector<WorldForce>& forces, std::vector<WorldBody>& bodies,
                    StepStats& st) {
  const double slop = s.joint_projection;
  if (!(slop > 0)) return;
  for (int pass = 0; pass < kProjectionPasses; ++pass) {
    bool moved = false;
    for (const WorldForce& f : forces) {
      if (!f.alive) continue;
      const HeldPoints h = held_points(f.type);
      if (h.a < 0) continue;
      const Side a = side(bodies, f.a, read_vec3(f.instance, h.a));
      const Side b = side(bodies, f.b, read_vec3(f.instance, h.b));
      if (!a.moves && !b.moves) continue;
      const Vec3d gap = (b.x + b.r) - (a.x + a.r);
      const double len = norm(gap);
      if (len <= slop) continue;
      // Close the gap to the projection distance: K P = the excess, K P = dp_a - dp_b per unit P.
      const Vec3d excess = gap * ((len - slop) / len);
      const Vec3d axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
      Vec3d col[3];
      for (int k = 0; k < 3; ++k) col[k] = point_moves(a, axes[k]) + point_moves(b, axes[k]);
      Vec3d P;
      if (!solve3(col, excess, P)) continue;
      if (a.moves) move(bodies[f.a], a, P);
      if (b.moves) move(bodies[f.b], b, -P);
      if (pass == 0) ++st.projected_joints;
      moved = true;
    }
    if (!moved) break;
  }
}

}  // namespace cellphys::ppe

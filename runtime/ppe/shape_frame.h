// A body pose as a frame for the world queries (shape_ray, shape_distance, shape_sweep):
// rotation, translation and uniform scale, with the maps between world and the shape's own
// unit-scale coordinates. Double precision, like the narrow phase.
#pragma once
#include "runtime/base/quat.h"
#include "runtime/spu/shape.h"

namespace cellphys::ppe {

struct ShapeFrame {
  Mat3d R;  // body to world
  Vec3d t;
  double s = 1.0;

  /// The pose's frame; a non-unit quaternion is normalised (a zero one is the identity).
  static ShapeFrame of(const spu::Pose& p) {
    ShapeFrame f;
    Quatd q = Quatd::load(p.orientation);
    const double n = norm(q);
    q = n > 0.0 && std::isfinite(n) ? Quatd{q.w / n, q.x / n, q.y / n, q.z / n} : Quatd{1, 0, 0, 0};
    f.R = quat_to_matrix(q);
    f.t = Vec3d::load(p.position);
    f.s = p.scale;
    return f;
  }
  Vec3d rotate(const Vec3d& v) const { return mul(R, v); }
  Vec3d unrotate(const Vec3d& v) const { return mul_transpose(R, v); }
  /// A world point in unit-scale shape coordinates, and back.
  Vec3d to_shape(const Vec3d& x) const { return unrotate(x - t) * (1.0 / s); }
  Vec3d to_world(const Vec3d& x) const { return t + rotate(x * s); }
};

}  // namespace cellphys::ppe

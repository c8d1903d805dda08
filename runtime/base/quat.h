// Quaternions over a scalar (Quatd), w x y z, as rotations: the Hamilton product, the unit
// quaternion of a rotation vector, and the rotation matrix. Each component in one fixed order
// of operations, like vec3.h.
#pragma once
#include <cmath>

#include "runtime/base/mat3.h"
#include "runtime/base/trig.h"
#include "runtime/base/vec3.h"

namespace cellphys {

template <class T>
struct Quat {
  T w, x, y, z;

  /// The four values at p (w x y z), converted to T.
  template <class S>
  static Quat load(const S* p) {
    return {T(p[0]), T(p[1]), T(p[2]), T(p[3])};
  }
};

using Quatd = Quat<double>;

template <class T>
Quat<T> quat_mul(const Quat<T>& a, const Quat<T>& b) {
  return {a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
          a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}

template <class T>
T norm(const Quat<T>& q) {
  using std::sqrt;  // and a lane type's own (double_lanes.h)
  return sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
}

template <class T>
Quat<T> quat_normalized(const Quat<T>& q) {
  const T n = norm(q);
  return {q.w / n, q.x / n, q.y / n, q.z / n};
}

/// exp of a rotation vector: the unit quaternion rotating by |r| about r.
template <class T>
Quat<T> quat_exp(const Vec3<T>& r) {
  const T a = norm(r);
  double sine, cosine;  // the project's own: the same bits on every machine (trig.h)
  sin_cos(double(T(0.5) * a), &sine, &cosine);
  // sin(a/2)/a by its series near 0, where the quotient loses digits
  const T s = a < T(1e-4) ? T(0.5) - a * a / T(48) : T(sine) / a;
  return {T(cosine), s * r.x, s * r.y, s * r.z};
}

/// The rotation matrix of a unit quaternion (body to world).
template <class T>
Mat3<T> quat_to_matrix(const Quat<T>& q) {
  const T w = q.w, x = q.x, y = q.y, z = q.z;
  return {{{1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)},
           {2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)},
           {2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)}}};
}

}  // namespace cellphys

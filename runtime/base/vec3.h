// 3-vectors over a scalar (Vec3f, Vec3d). Each operation evaluates its components in one
// fixed order (a dot product is x + y, then + z), so code written with these operators gives
// the same bits as the same expression written out by hand: the build contracts nothing
// (-ffp-contract=off), and a + b + c adds left to right like the scalar code it replaces.
// No default member values: arrays of them (the narrow phase's polytopes) stay uninitialised
// scratch; write Vec3d{} for zero.
#pragma once
#include <algorithm>
#include <cmath>

namespace cellphys {

template <class T>
struct Vec3 {
  using scalar = T;
  T x, y, z;

  /// The first three values at p, converted to T.
  template <class S>
  static Vec3 load(const S* p) {
    return {T(p[0]), T(p[1]), T(p[2])};
  }
  /// Component k (0, 1, 2): for code that loops over the axes.
  T operator[](int k) const { return k == 0 ? x : (k == 1 ? y : z); }
};

using Vec3f = Vec3<float>;
using Vec3d = Vec3<double>;

// The scalar parameters are not deduced (Vec3<T>::scalar), so v * 2 and v * h with a float h
// convert the scalar to T first, as the scalar expressions do.
template <class T>
Vec3<T> operator+(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
template <class T>
Vec3<T> operator-(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
template <class T>
Vec3<T> operator-(const Vec3<T>& a) {
  return {-a.x, -a.y, -a.z};
}
template <class T>
Vec3<T> operator*(const Vec3<T>& a, typename Vec3<T>::scalar s) {
  return {a.x * s, a.y * s, a.z * s};
}
/// Divides each component (not the same bits as a * (1 / s)).
template <class T>
Vec3<T> operator/(const Vec3<T>& a, typename Vec3<T>::scalar s) {
  return {a.x / s, a.y / s, a.z / s};
}

template <class T>
T dot(const Vec3<T>& a, const Vec3<T>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
template <class T>
Vec3<T> cross(const Vec3<T>& a, const Vec3<T>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <class T>
T squared_norm(const Vec3<T>& a) {
  return dot(a, a);
}
template <class T>
T norm(const Vec3<T>& a) {
  using std::sqrt;  // and a lane type's own (double_lanes.h)
  return sqrt(dot(a, a));
}

/// Componentwise std::min and std::max (a box's corners).
template <class T>
Vec3<T> min(const Vec3<T>& a, const Vec3<T>& b) {
  return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
template <class T>
Vec3<T> max(const Vec3<T>& a, const Vec3<T>& b) {
  return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}

}  // namespace cellphys

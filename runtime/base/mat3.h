// 3x3 matrices over a scalar (Mat3d): products with a vector, and a packed symmetric tensor
// (xx yy zz xy xz yz, as inertia is stored) turned into a matrix or into a new frame. Sums
// run in index order, from zero where a product is accumulated, so results are the bits of
// the same loops written out.
#pragma once
#include "runtime/base/vec3.h"

namespace cellphys {

template <class T>
struct Mat3 {
  T m[3][3];
};

using Mat3d = Mat3<double>;

template <class T>
Vec3<T> mul(const Mat3<T>& A, const Vec3<T>& v) {
  return {A.m[0][0] * v.x + A.m[0][1] * v.y + A.m[0][2] * v.z, A.m[1][0] * v.x + A.m[1][1] * v.y + A.m[1][2] * v.z,
          A.m[2][0] * v.x + A.m[2][1] * v.y + A.m[2][2] * v.z};
}

/// A^T v.
template <class T>
Vec3<T> mul_transpose(const Mat3<T>& A, const Vec3<T>& v) {
  return {A.m[0][0] * v.x + A.m[1][0] * v.y + A.m[2][0] * v.z, A.m[0][1] * v.x + A.m[1][1] * v.y + A.m[2][1] * v.z,
          A.m[0][2] * v.x + A.m[1][2] * v.y + A.m[2][2] * v.z};
}

/// The symmetric matrix of s6 = xx yy zz xy xz yz.
template <class T, class S>
Mat3<T> symmetric(const S* s) {
  return {{{T(s[0]), T(s[3]), T(s[4])}, {T(s[3]), T(s[1]), T(s[5])}, {T(s[4]), T(s[5]), T(s[2])}}};
}

/// R S R^T for a symmetric S.
template <class T>
Mat3<T> rotate_sym_matrix(const Mat3<T>& R, const Mat3<T>& S3) {
  Mat3<T> RS{}, out{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) RS.m[i][j] += R.m[i][k] * S3.m[k][j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) out.m[i][j] += RS.m[i][k] * R.m[j][k];
  return out;
}

/// R S R^T for a symmetric S given as xx yy zz xy xz yz.
template <class T, class S>
Mat3<T> rotate_sym(const Mat3<T>& R, const S* s6) {
  return rotate_sym_matrix(R, symmetric<T>(s6));
}

}  // namespace cellphys

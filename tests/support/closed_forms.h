// Closed-form solutions the accuracy tests compare the kernel against (header-only, double).
//  - the undamped and underdamped linear oscillator;
//  - the torque-free asymmetric rigid body: body-frame angular velocity in Jacobi elliptic
//    functions (Landau & Lifshitz, Mechanics, section 37), with sn/cn/dn by the arithmetic-
//    geometric mean (Abramowitz & Stegun 16.4) and the start phase from the incomplete
//    elliptic integral of the first kind (std::ellint_1).
#pragma once
#include <array>
#include <cmath>
#include <utility>

namespace cellphys::test_support {

/// x'' + 2 zeta w x' + w^2 x = 0 with x(0) = x0, x'(0) = v0, zeta < 1: (x, v) at t.
inline std::pair<double, double> damped_oscillator(double w, double zeta, double x0, double v0, double t) {
  const double wd = w * std::sqrt(1.0 - zeta * zeta), s = zeta * w;
  const double c1 = x0, c2 = (v0 + s * x0) / wd;
  const double e = std::exp(-s * t), c = std::cos(wd * t), sn = std::sin(wd * t);
  const double x = e * (c1 * c + c2 * sn);
  const double v = e * (-s * (c1 * c + c2 * sn) + (-c1 * wd * sn + c2 * wd * c));
  return {x, v};
}

/// Jacobi elliptic functions sn, cn, dn of u for parameter m = k^2 in [0, 1).
inline void jacobi_sncndn(double u, double m, double* sn, double* cn, double* dn) {
  if (m < 1e-15) {
    *sn = std::sin(u), *cn = std::cos(u), *dn = 1.0;
    return;
  }
  constexpr int kMax = 32;
  double a[kMax + 1], c[kMax + 1];
  a[0] = 1.0;
  double b = std::sqrt(1.0 - m);
  c[0] = std::sqrt(m);
  int n = 0;
  while (std::fabs(c[n]) > 1e-16 && n < kMax) {
    const double an = 0.5 * (a[n] + b);
    c[n + 1] = 0.5 * (a[n] - b);
    b = std::sqrt(a[n] * b);
    a[n + 1] = an;
    ++n;
  }
  double phi = std::ldexp(a[n] * u, n), phi_prev = phi;
  for (int j = n; j >= 1; --j) {
    phi_prev = phi;
    phi = 0.5 * (phi + std::asin(c[j] / a[j] * std::sin(phi)));
  }
  *sn = std::sin(phi);
  *cn = std::cos(phi);
  *dn = n > 0 ? std::cos(phi) / std::cos(phi_prev - phi) : 1.0;
}

/// Incomplete elliptic integral of the first kind F(phi | m) for any real phi.
inline double elliptic_f(double phi, double m) {
  const double k = std::sqrt(m);
  const double K = std::comp_ellint_1(k);
  const double turns = std::round(phi / M_PI);
  const double rest = phi - turns * M_PI;  // in [-pi/2, pi/2]
  return 2.0 * K * turns + std::ellint_1(k, rest);
}

/// Torque-free rotation of a body with distinct principal moments I (body axes x y z) from
/// the body-frame angular velocity w0: the body-frame angular velocity at any time.
class TorqueFreeBody {
 public:
  TorqueFreeBody(const std::array<double, 3>& I, const std::array<double, 3>& w0) {
    // order the axes by moment: p[0] smallest, p[2] largest
    int p[3] = {0, 1, 2};
    for (int i = 0; i < 3; ++i)
      for (int j = i + 1; j < 3; ++j)
        if (I[p[j]] < I[p[i]]) std::swap(p[i], p[j]);
    double E2 = 0, M2 = 0;  // 2E and M^2
    for (int k = 0; k < 3; ++k) E2 += I[k] * w0[k] * w0[k], M2 += I[k] * I[k] * w0[k] * w0[k];
    // Landau-Lifshitz assume M^2 > 2 E I2; otherwise exchange axes 1 and 3, which reverses time
    reverse_ = M2 < E2 * I[p[1]];
    if (reverse_) std::swap(p[0], p[2]);
    // a cyclic relabelling keeps Euler's equations; (x y z) -> (p0 p1 p2) is odd when it
    // is not cyclic, which also reverses time
    const bool cyclic = (p[1] == (p[0] + 1) % 3);
    double sign_t = (reverse_ ? -1.0 : 1.0) * (cyclic ? 1.0 : -1.0);
    // in the L&L ordering the same formulas hold either way (see the header comment)
    const double I1 = I[p[0]], I2 = I[p[1]], I3 = I[p[2]];
    A_[0] = std::sqrt((E2 * I3 - M2) / (I1 * (I3 - I1)));
    A_[1] = std::sqrt((E2 * I3 - M2) / (I2 * (I3 - I2)));
    A_[2] = std::sqrt((M2 - E2 * I1) / (I3 * (I3 - I1)));
    m_ = (I2 - I1) * (E2 * I3 - M2) / ((I3 - I2) * (M2 - E2 * I1));
    const double lambda = std::sqrt((I3 - I2) * (M2 - E2 * I1) / (I1 * I2 * I3));
    for (int k = 0; k < 3; ++k) axis_[k] = p[k];
    sigma_ = w0[p[2]] < 0 ? -1.0 : 1.0;
    lambda_ = sign_t * sigma_ * lambda;
    tau0_ = elliptic_f(std::atan2(w0[p[1]] / A_[1], w0[p[0]] / A_[0]), m_);
  }

  /// Body-frame angular velocity at time t.
  std::array<double, 3> omega(double t) const {
    double sn, cn, dn;
    jacobi_sncndn(lambda_ * t + tau0_, m_, &sn, &cn, &dn);
    std::array<double, 3> w{};
    w[axis_[0]] = A_[0] * cn;
    w[axis_[1]] = A_[1] * sn;
    w[axis_[2]] = sigma_ * A_[2] * dn;
    return w;
  }
  double parameter() const { return m_; }

 private:
  double A_[3] = {}, m_ = 0, lambda_ = 0, tau0_ = 0, sigma_ = 1;
  int axis_[3] = {0, 1, 2};
  bool reverse_ = false;
};

}  // namespace cellphys::test_support

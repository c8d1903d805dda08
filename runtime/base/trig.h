// Sine and cosine that give the same bits on every machine and SIMD path. The C library's
// sin and cos are not required to be correctly rounded, and glibc picks among its own
// variants by the CPU it runs on (FMA or not), so a rotation integrated with them could
// differ in the last bit between two machines. These use only IEEE-754 add, subtract and
// multiply (the build never contracts them into fused operations), so they are reproducible
// wherever double is IEEE binary64.
//
// Accuracy: within 2 ulp of the true value for |x| < 1e5 (Cody–Waite reduction by π/2 in
// three parts, then Taylor polynomials of degree 15 and 16 on [−π/4, π/4], whose
// truncation error is under 1e-16 there). Beyond 1e5 the reduction loses digits but stays
// deterministic; rotation angles in a step are far smaller.
#pragma once

#include <cmath>

namespace cellphys {

namespace trig_detail {
// sin(r) and cos(r) for |r| <= π/4 by Horner's rule in r².
inline double sin_poly(double r) {
  const double z = r * r;
  double p = -1.0 / 1307674368000.0;         // -1/15!
  p = p * z + 1.0 / 6227020800.0;            //  1/13!
  p = p * z - 1.0 / 39916800.0;              // -1/11!
  p = p * z + 1.0 / 362880.0;                //  1/9!
  p = p * z - 1.0 / 5040.0;                  // -1/7!
  p = p * z + 1.0 / 120.0;                   //  1/5!
  p = p * z - 1.0 / 6.0;                     // -1/3!
  return r + r * (z * p);
}
inline double cos_poly(double r) {
  const double z = r * r;
  double p = 1.0 / 20922789888000.0;         //  1/16!
  p = p * z - 1.0 / 87178291200.0;           // -1/14!
  p = p * z + 1.0 / 479001600.0;             //  1/12!
  p = p * z - 1.0 / 3628800.0;               // -1/10!
  p = p * z + 1.0 / 40320.0;                 //  1/8!
  p = p * z - 1.0 / 720.0;                   // -1/6!
  p = p * z + 1.0 / 24.0;                    //  1/4!
  return (1.0 - 0.5 * z) + z * (z * p);
}
}  // namespace trig_detail

/// sin(x) and cos(x), bit-identical on every machine (see above).
inline void sin_cos(double x, double* s, double* c) {
  // π/2 = P1 + P2 + P3; P1 and P2 have 33 significant bits, so k·P1 and k·P2 are exact for
  // |k| < 2^20 and the reduced argument keeps its digits.
  constexpr double kTwoOverPi = 0.63661977236758134308;
  constexpr double P1 = 1.5707963267341256e+00;
  constexpr double P2 = 6.07710050630396597660e-11;
  constexpr double P3 = 2.02226624879595063154e-21;
  const double k = std::floor(x * kTwoOverPi + 0.5);
  const double r = ((x - k * P1) - k * P2) - k * P3;
  const double sr = trig_detail::sin_poly(r), cr = trig_detail::cos_poly(r);
  const long long q = static_cast<long long>(std::fmod(k, 4.0));  // exact; -3..3
  switch (q < 0 ? q + 4 : q) {
    case 0: *s = sr, *c = cr; break;
    case 1: *s = cr, *c = -sr; break;
    case 2: *s = -sr, *c = -cr; break;
    default: *s = -cr, *c = sr; break;
  }
}

}  // namespace cellphys

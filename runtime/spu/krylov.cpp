// Krylov solvers on the block-Jacobi scaled island system, and the sparse-LU oracle.
#include "runtime/spu/krylov.h"

#include <Eigen/Sparse>
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "cellphys/gen/block_ops.h"
#include "runtime/base/enum_names.h"
#include "runtime/base/simd.h"

namespace cellphys::spu {
namespace {

// dst = a + s b (the reference design's vec_add_scaled); dst may alias a or b.
void add_scaled(int n, float* dst, const float* a, float s, const float* b) {
  using namespace simd;
  const vf8 ss = splats<vf8>(s);
  for (int i = 0; i < n; ++i)
    store(dst + kVecFloats * i,
          madd(ss, load<vf8>(b + kVecFloats * i), load<vf8>(a + kVecFloats * i)));
}

float norm(int n, const float* a) { return std::sqrt(dot(n, a, a)); }

int iteration_limit(const BlockRowMatrix& A, const SolveSettings& s) {
  return s.max_iterations > 0 ? s.max_iterations : 2 * 6 * A.n;  // the reference design's max_iters
}

// The smallest residual so far and where: a solve that has not bettered it for as many
// iterations as it took to reach it (and at least kStallIterations) has diverged. CGS's
// residual jumps by orders of magnitude in its first iterations and comes back; once its
// iterates blow up they stay up, and a halved step costs less than running to the limit.
constexpr int kStallIterations = 100;
struct Progress {
  float smallest = std::numeric_limits<float>::infinity();
  int at = 0;
};

// The checks at the head of every iteration: the residual not finite, converged, over the
// iteration limit, or diverged. True when the solve is over, with res.code and res.residual set.
bool finished(float rr, float norm_b, int iter, int max_iters, const SolveSettings& s, Progress& p, SolveResult& res) {
  res.residual = rr / norm_b;
  // NaN fails every comparison below, so test it first rather than run to max_iters.
  if (!std::isfinite(res.residual)) return res.code = kNotFinite, true;
  if (res.residual < s.rel_tol || rr < s.abs_tol) return res.code = kConverged, true;
  if (iter >= max_iters) return res.code = kMaxIterations, true;
  if (res.residual < p.smallest) p.smallest = res.residual, p.at = iter;
  if (iter - p.at > std::max(kStallIterations, p.at)) return res.code = kDiverged, true;
  return false;
}

// A scaled system with no block off its unit diagonal: bodies that touch nothing but the world.
bool is_identity(const BlockRowMatrix& A) { return A.unit_diagonal && A.row_start[A.n] == A.row_start[0]; }

// Every float of a[0, count) is +0 (not -0): b - a is then b to the bit.
bool all_positive_zero(int count, const float* a) {
  uint32_t bits = 0;
  for (int i = 0; i < count; ++i) {
    uint32_t u;
    std::memcpy(&u, a + i, sizeof u);
    bits |= u;
  }
  return bits == 0;
}

// r = b - A x, with tmp as scratch.
void residual(const BlockRowMatrix& A, const float* b, const float* x, float* r, float* tmp, RowSharer* sharer) {
  spmv(A, x, tmp, sharer);
  add_scaled(A.n, r, b, -1.0f, tmp);
}

}  // namespace

SolveResult cgs(const BlockRowMatrix& A, const float* b, float* x, float* work, const SolveSettings& s) {
  const int n = A.n;
  const int nv = kVecFloats * n;
  float* r = work;
  float* r_tilde = work + 1 * nv;
  float* u = work + 2 * nv;
  float* p = work + 3 * nv;
  float* q = work + 4 * nv;
  float* v_hat = work + 5 * nv;
  float* q_hat = work + 6 * nv;  // also the scratch for A x below
  static_assert(kCgsWorkVectors == 7, "cgs uses seven work vectors");

  SolveResult res;
  const float norm_b = norm(n, b);
  if (norm_b <= s.zero_rhs) return res;  // the reference design: nothing to solve, x untouched
  const int max_iters = iteration_limit(A, s);
  Progress progress;

  if (is_identity(A) && s.rel_tol > 0.0f) {
    // Bodies that touch only the world (most of a sparse world's islands): the scaled system
    // is I, and the first iteration below is exact. It is run as below with A p = p and
    // A u = u, so x gets the same bits; its residual is then 0, under any rel_tol > 0.
    if (all_positive_zero(nv, x)) {
      // From x = +0 (how a step starts each solve) that iteration has a closed form: r = b - 0
      // is b to the bit, so |r| is norm_b; past the check, rho = |b|^2 is finite and nonzero,
      // alpha = rho / rho = 1, q = r - r = +0, u = r + q, x = 0 + u: b with -0 made +0; and
      // r - u is zero. The same bits as the steps below, without their chain of reductions.
      if (finished(norm_b, norm_b, 0, max_iters, s, progress, res)) return res;
      ++res.iterations;
      add_scaled(n, x, x, 1.0f, b);  // x = b + (+0)
      finished(0.0f, norm_b, 1, max_iters, s, progress, res);
      return res;
    }
    add_scaled(n, r, b, -1.0f, x);  // r = b - x
    if (finished(norm(n, r), norm_b, 0, max_iters, s, progress, res)) return res;
    ++res.iterations;
    const float rho = dot(n, r, r);  // nonzero: |r| is finite and not below the tolerances
    const float alpha = rho / rho;
    add_scaled(n, q, r, -alpha, r);  // q = u - alpha v_hat, with u = p = v_hat = r
    add_scaled(n, u, r, 1.0f, q);    // u = u + q
    axpy(n, alpha, u, x);
    axpy(n, -alpha, u, r);  // q_hat = u
    finished(norm(n, r), norm_b, 1, max_iters, s, progress, res);
    return res;
  }

  residual(A, b, x, r, q_hat, s.sharer);
  copy(n, r, r_tilde);

  float rho_1 = 0.0f, rho_2 = 0.0f;
  for (int iter = 0;; ++iter) {
    if (finished(norm(n, r), norm_b, iter, max_iters, s, progress, res)) return res;
    ++res.iterations;  // the reference design's ++*Pdest_num_iters: counts a breakdown pass too

    rho_1 = dot(n, r_tilde, r);
    if (rho_1 == 0.0f) { res.code = kRhoZero; return res; }

    if (iter == 0) {
      copy(n, r, u);
      copy(n, u, p);
    } else {
      const float beta = rho_1 / rho_2;
      add_scaled(n, u, r, beta, q);  // u = r + beta q
      xpby(n, q, beta, p);           // p = q + beta p
      xpby(n, u, beta, p);           // p = u + beta p
    }

    // Preconditioner: block-Jacobi was applied once at assembly (block_sparse.h), so the
    // reference design's precond.solve is the identity here: p_hat = p.
    const float* p_hat = p;
    spmv(A, p_hat, v_hat, s.sharer);
    const float den = dot(n, r_tilde, v_hat);
    if (den == 0.0f) { res.code = kDenominatorZero; return res; }
    const float alpha = rho_1 / den;

    add_scaled(n, q, u, -alpha, v_hat);  // q = u - alpha v_hat
    axpy(n, 1.0f, q, u);                 // u = u + q
    const float* u_hat = u;              // identity preconditioner, as p_hat
    axpy(n, alpha, u_hat, x);
    spmv(A, u_hat, q_hat, s.sharer);
    axpy(n, -alpha, q_hat, r);

    rho_2 = rho_1;
  }
}

SolveResult bicgstab(const BlockRowMatrix& A, const float* b, float* x, float* work,
                     const SolveSettings& s) {
  const int n = A.n;
  const int nv = kVecFloats * n;
  float* r = work;
  float* r_tilde = work + 1 * nv;
  float* p = work + 2 * nv;
  float* v = work + 3 * nv;
  float* sv = work + 4 * nv;
  float* t = work + 5 * nv;
  // work + 6 * nv is unused: the count matches CGS so one scratch area serves both.
  static_assert(kBicgstabWorkVectors >= 6, "bicgstab uses six work vectors");

  SolveResult res;
  const float norm_b = norm(n, b);
  if (norm_b <= s.zero_rhs) return res;  // same early out as the reference design's CGS
  const int max_iters = iteration_limit(A, s);

  residual(A, b, x, r, v, s.sharer);
  copy(n, r, r_tilde);

  float rho_prev = 1.0f, alpha = 1.0f, omega = 1.0f;
  Progress progress;
  for (int iter = 0;; ++iter) {
    if (finished(norm(n, r), norm_b, iter, max_iters, s, progress, res)) return res;
    ++res.iterations;

    const float rho = dot(n, r_tilde, r);
    if (rho == 0.0f) { res.code = kRhoZero; return res; }

    if (iter == 0) {
      copy(n, r, p);
    } else {
      // omega = 0 ((t, s) = 0) would make beta infinite: the same kind of breakdown as den = 0.
      if (omega == 0.0f) { res.code = kDenominatorZero; return res; }
      const float beta = (rho / rho_prev) * (alpha / omega);
      axpy(n, -omega, v, p);  // p = r + beta (p - omega v)
      xpby(n, r, beta, p);
    }

    // Identity preconditioner (block-Jacobi applied at assembly): p_hat = p, s_hat = s.
    spmv(A, p, v, s.sharer);
    const float den = dot(n, r_tilde, v);
    if (den == 0.0f) { res.code = kDenominatorZero; return res; }
    alpha = rho / den;

    add_scaled(n, sv, r, -alpha, v);  // s = r - alpha v
    const float ss = norm(n, sv);
    if (ss / norm_b < s.rel_tol || ss < s.abs_tol) {  // half-step already good enough
      axpy(n, alpha, p, x);
      res.residual = ss / norm_b;
      res.code = kConverged;
      return res;
    }

    spmv(A, sv, t, s.sharer);
    const float tt = dot(n, t, t);
    if (tt == 0.0f) { res.code = kDenominatorZero; return res; }
    omega = dot(n, t, sv) / tt;

    axpy(n, alpha, p, x);
    axpy(n, omega, sv, x);
    add_scaled(n, r, sv, -omega, t);  // r = s - omega t
    rho_prev = rho;
  }
}

SolveResult direct_lu(const BlockRowMatrix& A, const float* b, float* x) {
  using gen::padded;
  const int n = A.n;
  const int dim = 6 * n;
  SolveResult res;
  if (n == 0) return res;

  // Logical 6x6 entries only; duplicate blocks are summed, as spmv does.
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(static_cast<size_t>(36) * (n + A.row_start[n]));
  auto add_block = [&](int bi, int bj, const float* B) {
    for (int c = 0; c < 6; ++c)
      for (int r = 0; r < 6; ++r) entries.emplace_back(6 * bi + r, 6 * bj + c, B[8 * c + padded(r)]);
  };
  for (int i = 0; i < n; ++i) {
    if (A.unit_diagonal) {
      for (int r = 0; r < 6; ++r) entries.emplace_back(6 * i + r, 6 * i + r, 1.0);
    } else {
      add_block(i, i, A.diag + kBlockFloats * i);
    }
    for (int32_t k = A.row_start[i]; k < A.row_start[i + 1]; ++k)
      add_block(i, A.col[k], A.blocks + kBlockFloats * k);
  }
  Eigen::SparseMatrix<double> M(dim, dim);
  M.setFromTriplets(entries.begin(), entries.end());
  M.makeCompressed();

  Eigen::VectorXd bd(dim);
  for (int i = 0; i < n; ++i)
    for (int r = 0; r < 6; ++r) bd(6 * i + r) = b[kVecFloats * i + padded(r)];

  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
  lu.compute(M);
  Eigen::VectorXd xd;
  if (lu.info() == Eigen::Success) xd = lu.solve(bd);
  // Also reject what float cannot hold (the cast below would be undefined).
  if (lu.info() != Eigen::Success || !xd.allFinite() ||
      xd.cwiseAbs().maxCoeff() > std::numeric_limits<float>::max()) {
    res.code = kNotFinite;
    res.residual = std::numeric_limits<float>::quiet_NaN();
    return res;
  }

  // The float x actually returned, for an honest residual. Rounded here rather than read
  // back from x: GCC 12.2 -O3 (SLP) drops the float rounding on such a read-back.
  const Eigen::VectorXd xf = xd.cast<float>().cast<double>();
  for (int i = 0; i < n; ++i) {
    float* xi = x + kVecFloats * i;
    for (int r = 0; r < 6; ++r) xi[padded(r)] = static_cast<float>(xf(6 * i + r));
    xi[3] = xi[7] = 0.0f;
  }
  const double nb = bd.norm();
  const double nr = (bd - M * xf).norm();
  res.residual = static_cast<float>(nb > 0.0 ? nr / nb : nr);
  if (!std::isfinite(res.residual)) res.code = kNotFinite;
  return res;
}

namespace {
constexpr const char* kSolverNames[kNumSolvers] = {"cgs", "bicgstab", "direct"};
}  // namespace

const char* solver_name(Solver s) { return base::name_of(kSolverNames, s); }
bool parse_solver(const std::string& name, Solver* out) { return base::value_named(kSolverNames, name, out); }
std::string solver_names() { return base::all_names(kSolverNames); }

SolveResult solve(Solver which, const BlockRowMatrix& A, const float* b, float* x, float* work,
                  const SolveSettings& s) {
  switch (which) {
    case Solver::cgs: return cgs(A, b, x, work, s);
    case Solver::bicgstab: return bicgstab(A, b, x, work, s);
    case Solver::direct: return direct_lu(A, b, x);
  }
  return SolveResult{kNotFinite, 0, std::numeric_limits<float>::quiet_NaN()};
}

}  // namespace cellphys::spu

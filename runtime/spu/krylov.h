// Linear solvers for the island system Â Δu = b̂ (block_sparse.h). All of them work in
// caller-provided memory (the local store) and allocate nothing, except the direct LU,
// which is the test oracle and a reference point on the charts and uses the heap.
#pragma once
#include <cstdint>
#include <string>

#include "runtime/spu/block_sparse.h"

namespace cellphys::spu {

enum class Solver : uint32_t { cgs = 0, bicgstab = 1, direct = 2 };
inline constexpr int kNumSolvers = 3;
const char* solver_name(Solver s);
bool parse_solver(const std::string& name, Solver* out);
/// "cgs, bicgstab, direct": for messages and help text.
std::string solver_names();

/// The reference design's failure codes, kept: 0 converged, 1 max iterations, 2 rho = 0, 3 denominator = 0;
/// and 4 not finite, 5 diverged (no smaller residual for as many iterations as the smallest took,
/// and at least 100: the iterates blew up, and a halved step costs less than running to the limit).
enum SolveCode : int {
  kConverged = 0,
  kMaxIterations = 1,
  kRhoZero = 2,
  kDenominatorZero = 3,
  kNotFinite = 4,
  kDiverged = 5
};

struct SolveSettings {
  float rel_tol = 1e-3f;   // the reference design's rel_tol: stop when |r| / |b| < rel_tol
  float abs_tol = 1e-3f;   // the reference design's abs_tol: or when |r| < abs_tol
  int max_iterations = 0;  // 0: the reference design's rule, 2 * 6 * n
  // |b| at or below which there is nothing to solve and x is returned untouched. The reference design
  // used 1e-4 (absolute); the kernel uses 0, because b = h W g shrinks with the step and a
  // small but real right-hand side (a spring near its crossing, a Rosenbrock substep)
  // must still be solved.
  float zero_rhs = 1e-4f;
  // Who may take rows of a big system's products (spmv): how the work is run, not what it
  // computes; the result is the same bits with or without.
  RowSharer* sharer = nullptr;
};

struct SolveResult {
  int code = kConverged;
  int iterations = 0;
  float residual = 0.0f;  // |r| / |b| at exit (recurrence residual for the Krylov methods)
};

/// Vectors of scratch each solver needs (n * kVecFloats floats each).
inline constexpr int kCgsWorkVectors = 7;
inline constexpr int kBicgstabWorkVectors = 7;

/// Conjugate gradient squared, as the reference design's SPU_conjugate_gradient_squared (stopping rule,
/// iteration limit and failure codes kept). x holds the initial guess and receives the solution.
SolveResult cgs(const BlockRowMatrix& A, const float* b, float* x, float* work, const SolveSettings& s);

/// BiCGSTAB (van der Vorst), same settings and codes; also two mat-vecs per iteration.
SolveResult bicgstab(const BlockRowMatrix& A, const float* b, float* x, float* work, const SolveSettings& s);

/// Sparse LU (Eigen) of the same matrix, in double: the oracle. Code kNotFinite when singular.
SolveResult direct_lu(const BlockRowMatrix& A, const float* b, float* x);

SolveResult solve(Solver which, const BlockRowMatrix& A, const float* b, float* x, float* work,
                  const SolveSettings& s);

}  // namespace cellphys::spu

"""Symbolic pieces of the generated block operations (6x6 logical blocks, padded 8x6)."""
import sympy as sp


def padded_row(r):
    """Logical row 0..5 -> row in the padded 8-float column (x y z _ x y z _)."""
    return r if r < 3 else r + 1


def _inverse3(M, name):
    """Adjugate inverse of a 3x3 as (determinant symbol, stage of (symbol, expression))."""
    det = sp.Symbol(f"{name}_det", real=True)
    adj = M.adjugate()
    stage = [(det, M.det(method="berkowitz"))]
    inv = sp.zeros(3, 3)
    rdet = sp.Symbol(f"{name}_rdet", real=True)
    stage.append((rdet, 1 / det))
    for r in range(3):
        for c in range(3):
            s = sp.Symbol(f"{name}_{r}{c}", real=True)
            stage.append((s, adj[r, c] * rdet))
            inv[r, c] = s
    return det, stage, inv


def _name_matrix(M, name):
    out, stage = sp.zeros(*M.shape), []
    for r in range(M.rows):
        for c in range(M.cols):
            s = sp.Symbol(f"{name}_{r}{c}", real=True)
            stage.append((s, M[r, c]))
            out[r, c] = s
    return out, stage


def jacobi_inverse_stages():
    """Inverse of a 6x6 block [[P Q] [R S]] through the Schur complement of P.

    Straight-line code, no pivoting: the diagonal blocks of A = I - hW dF/du - h^2 W dF/ddelta
    have dominant translational and rotational 3x3 parts, and a zero or non-finite
    determinant is reported to the caller, which then falls back to a pivoting inverse.
    """
    A = sp.Matrix(6, 6, lambda r, c: sp.Symbol(f"a{r}{c}", real=True))
    P, Q, R, S = A[:3, :3], A[:3, 3:], A[3:, :3], A[3:, 3:]
    stages = []
    detP, st, Pi = _inverse3(P, "pi")
    stages.append(st)
    T, st = _name_matrix(R * Pi, "t")  # R P^-1
    stages.append(st)
    Sc, st = _name_matrix(S - T * Q, "sc")  # Schur complement
    stages.append(st)
    detS, st, Sci = _inverse3(Sc, "si")
    stages.append(st)
    U, st = _name_matrix(Pi * Q, "u")  # P^-1 Q
    stages.append(st)
    out = sp.zeros(6, 6)
    out[3:, 3:] = Sci
    out[3:, :3] = -Sci * T
    out[:3, 3:] = -U * Sci
    out[:3, :3] = Pi + U * Sci * T
    return A, stages, out, (detP, detS)


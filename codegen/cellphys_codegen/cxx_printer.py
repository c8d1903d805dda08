"""SymPy -> C++ for a generic scalar type S (float, double or a SIMD batch).

The numeric policy lives here: small integer powers are unrolled, x^(k/2) uses sqrt,
branches become select() so a SIMD batch evaluates both sides and picks per lane.
"""
import sympy as sp


class UnsupportedExpression(Exception):
    pass


def _num(x):
    if x.is_Integer:
        return f"S({int(x)})"
    v = float(x)
    return f"S({v!r})"


def _pow(base, e):
    b = cxx(base)
    if e.is_Integer:
        n = int(e)
        if 1 <= n <= 4:
            return "(" + "*".join([b] * n) + ")"
        if -4 <= n <= -1:
            return "(S(1)/(" + "*".join([b] * -n) + "))"
    if e.is_Rational and e.q == 2:
        n = int(e.p)
        root = f"sqrt({b})"
        if n == 1:
            return root
        if n == -1:
            return f"(S(1)/{root})"
        if n in (3, -3):
            s = f"({b}*{root})"
            return s if n > 0 else f"(S(1)/{s})"
    raise UnsupportedExpression(f"power {base}**{e} has no vectorisable form")


def cxx(e):
    if e.is_Symbol:
        return e.name
    if e.is_Number:
        if e in (sp.nan, sp.zoo, sp.oo, -sp.oo):
            raise UnsupportedExpression(f"non-finite constant {e}")
        return _num(e)
    if isinstance(e, sp.Add):
        terms = list(e.as_ordered_terms())
        out = cxx(terms[0])
        for t in terms[1:]:
            c, rest = t.as_coeff_Mul()
            if c.is_Number and c < 0:
                out += " - " + cxx(-t)
            else:
                out += " + " + cxx(t)
        return f"({out})"
    if isinstance(e, sp.Mul):
        c, rest = e.as_coeff_Mul()
        if c == -1:
            return f"(-{cxx(rest)})"
        num, den = [], []
        for a in e.as_ordered_factors():
            if a.is_Pow and a.exp.is_Number and a.exp < 0 and not (a.exp.is_Rational and a.exp.q == 2 and a.exp != -1):
                den.append(cxx(a.base) if a.exp == -1 else _pow(a.base, -a.exp))
            else:
                num.append(cxx(a))
        s = "*".join(num) if num else "S(1)"
        if den:
            s = f"{s}/({'*'.join(den)})"
        return f"({s})"
    if e.is_Pow:
        return _pow(e.base, e.exp)
    if isinstance(e, sp.Piecewise):
        *branches, last = e.args
        if last.cond != sp.true:
            raise UnsupportedExpression(f"piecewise without an otherwise-branch: {e}")
        out = cxx(last.expr)
        for expr, cond in reversed(branches):
            out = f"select({cxx(cond)}, {cxx(expr)}, {out})"
        return out
    if isinstance(e, sp.core.relational.Relational):
        ops = {sp.StrictGreaterThan: ">", sp.GreaterThan: ">=", sp.StrictLessThan: "<", sp.LessThan: "<="}
        if type(e) not in ops:
            raise UnsupportedExpression(f"comparison {e}")
        return f"({cxx(e.lhs)} {ops[type(e)]} {cxx(e.rhs)})"
    if isinstance(e, sp.Abs):
        return f"abs({cxx(e.args[0])})"
    if isinstance(e, sp.sign):
        x = cxx(e.args[0])
        return f"select({x} > S(0), S(1), select({x} < S(0), S(-1), S(0)))"
    if isinstance(e, sp.Heaviside):
        return f"select({cxx(e.args[0])} > S(0), S(1), S(0))"
    if isinstance(e, sp.atan2):
        return f"angle_of({cxx(e.args[0])}, {cxx(e.args[1])})"
    if isinstance(e, (sp.Max, sp.Min)):
        fn = "max" if isinstance(e, sp.Max) else "min"
        args = [cxx(a) for a in e.args]
        out = args[0]
        for a in args[1:]:
            out = f"{fn}({out}, {a})"
        return out
    raise UnsupportedExpression(f"{type(e).__name__} ({e}) cannot be emitted")


def emit(outputs, tmp_prefix="t"):
    """CSE over all outputs; returns (temporaries [(type, name, code)], output code list, op count).

    A temporary CSE pulls out of a condition is a lane mask for a SIMD batch, so its type is
    `auto`; every other one is S."""
    reps, reduced = sp.cse(outputs, symbols=sp.numbered_symbols(tmp_prefix), order="none")
    ops = sum(sp.count_ops(r) for _, r in reps) + sum(sp.count_ops(r) for r in reduced)
    tmps = [("auto" if isinstance(r, sp.logic.boolalg.Boolean) else "S", s.name, cxx(r)) for s, r in reps]
    return tmps, [cxx(r) for r in reduced], int(ops)

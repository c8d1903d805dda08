"""Force descriptors -> symbolic generalised forces and their Jacobians, per kernel variant."""
from dataclasses import dataclass, field
from pathlib import Path

import math

import sympy as sp

from . import kinematics as km
from . import names as naming
from . import yaml_loader
from .errors import DescriptorError
from .expressions import evaluate
from .structs import layout, unknown_keys

KINDS = ("global", "unary", "binary")
PARAM_TYPES = ("f32", "vec3")
FIELD_TYPES_OF = {"f32": ("f32",), "vec3": ("vec3", "vec3p")}  # the struct fields a param of each type may name
TOP_KEYS = {"name", "kind", "doc", "symmetric", "world_anchor", "joint", "holds_points", "instance", "params", "globals",
            "let", "apply"}
PARAM_KEYS = {"type", "min", "greater_than", "doc"}
GLOBAL_KEYS = {"type", "min", "greater_than", "doc", "default", "setting"}


@dataclass
class Param:
    name: str
    type: str
    doc: str
    min: float = None
    min_exclusive: bool = False  # declared with greater_than: the value must exceed min
    default: list = None  # globals only
    setting: str = None  # globals only: the place under a scene's settings (island_globals)

    @property
    def lanes(self):
        return 3 if self.type == "vec3" else 1


@dataclass
class Input:
    """One scalar input of a kernel and where the gather step reads it from."""
    symbol: sp.Symbol
    source: str  # "body", "param" or "global"
    body: int = 0  # body slot (0 = a, 1 = b) for source == "body"
    name: str = ""  # Rigid_Body field, instance field or Island_Params field
    lane: int = 0


@dataclass
class Block:
    kind: str  # "dd" (dF/d delta) or "du" (dF/du)
    row_body: int
    col_body: int
    exprs: list  # 36 entries, column-major 6x6


@dataclass
class Stage:
    """One let of a kernel: its value and, unless held, the derivatives that are not trivial."""
    origin: str  # the descriptor line it comes from, as the generated code names it
    held: bool  # a lagged() let, held through the step
    items: list  # [(symbol, expression)]


@dataclass
class Kernel:
    force: "Force"
    variant: str  # "body", "pair" or "world"
    num_bodies: int
    inputs: list
    forces: list  # 6 * num_bodies expressions
    blocks: list = field(default_factory=list)
    pre: dict = field(default_factory=dict)  # preamble symbol -> expression of the inputs
    pre_origins: dict = field(default_factory=dict)  # preamble symbol -> the let or apply entry that first used it
    stages: list = field(default_factory=list)  # one Stage per let, in order
    implicit: dict = field(default_factory=dict)  # outputs and block pairs of the implicit form
    apply_origin: str = ""  # the descriptor's apply list
    applies: list = field(default_factory=list)  # per apply entry: (origin, body slot or None for the world)
    joint_arms: dict = field(default_factory=dict)  # body slot -> held symbols (arm x, y, z, turn share): its arc

    @property
    def cxx_name(self):
        return f"{camel(self.force.name)}_{camel(self.variant)}_Kernel"


@dataclass
class Force:
    name: str
    kind: str
    doc: str
    symmetric: bool
    world_anchor: bool
    joint: bool  # the bodies it joins do not collide with each other
    params: list
    globals: list
    instance: object  # structs.Struct
    source: str
    kernels: list = field(default_factory=list)
    # the names of the two vec3 params a joint holds together (a's point in a's frame, b's in b's
    # or the world's): the world projects them back together when a step leaves them apart
    holds_points: tuple = ()


def camel(name):
    return "_".join(p[:1].upper() + p[1:] for p in name.split("_"))


def _params(path, raw, where, keys):
    if raw is None:
        return []
    if not isinstance(raw, dict):
        raise DescriptorError(path, where, "must be a mapping of name -> {type, ...}")
    out = []
    for name, spec in raw.items():
        loc = f"{where}.{name}"
        why = naming.problem(name, "param")
        if why:
            raise DescriptorError(path, loc, why)
        if name in km.FUNCTIONS or name in ("a", "b", "h"):
            raise DescriptorError(path, loc, f"{name!r} is a reserved name")
        if not isinstance(spec, dict):
            raise DescriptorError(path, loc, "must be a mapping with at least 'type'")
        unknown = unknown_keys(spec, keys)
        if unknown:
            raise DescriptorError(path, loc, f"unknown key(s) {unknown}")
        if "type" not in spec:
            raise DescriptorError(path, loc, "missing 'type'")
        if not isinstance(spec["type"], str) or spec["type"] not in PARAM_TYPES:
            raise DescriptorError(path, f"{loc}.type", f"unknown type {spec['type']!r} (known: {', '.join(PARAM_TYPES)})")
        if "min" in spec and "greater_than" in spec:
            raise DescriptorError(path, f"{loc}.greater_than", "give min or greater_than, not both")
        bound = "greater_than" if "greater_than" in spec else "min"
        p = Param(name, spec["type"], spec.get("doc", ""), spec.get(bound), bound == "greater_than")
        if p.min is not None and (isinstance(p.min, bool) or not isinstance(p.min, (int, float))
                                  or not math.isfinite(p.min)):
            raise DescriptorError(path, f"{loc}.{bound}", f"must be a number (and finite), got {p.min!r}")
        if "default" in spec or keys is GLOBAL_KEYS:
            d = spec.get("default")
            d = d if isinstance(d, list) else [d]
            if len(d) != p.lanes or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x)
                                        for x in d):
                raise DescriptorError(path, f"{loc}.default", f"must be {p.lanes} number(s), got {spec.get('default')!r} (YAML reads 1e5 as text: write 1.0e+5 or 100000.0)")
            p.default = [float(x) for x in d]
        if "setting" in spec:
            # a place of its own under a scene's settings, for a global several forces share
            # (joint.hertz): every part a lower_case identifier
            st = spec["setting"]
            parts = st.split(".") if isinstance(st, str) else []
            if not parts or any(naming.problem(x, "setting") or x != x.lower() for x in parts):
                raise DescriptorError(path, f"{loc}.setting", f"must be dotted lower_case identifiers, got {st!r}")
            p.setting = st
        out.append(p)
    return out


def _instance_struct(path, d, name, kind, params, structs):
    """The packed instance layout: a named struct descriptor, checked, or derived from params."""
    body_fields = {"global": ["body_a"], "unary": ["body_a"], "binary": ["body_a", "body_b"]}[kind]
    if "instance" in d:
        s = structs.get(d["instance"]) if isinstance(d["instance"], str) else None
        if s is None:
            raise DescriptorError(path, "instance", f"no struct descriptor named {d['instance']!r}")
        for p in params:
            f = s.field(p.name)
            if f is None or f.type not in FIELD_TYPES_OF[p.type] or f.count != 1:
                raise DescriptorError(path, f"params.{p.name}",
                                      f"struct {s.name} has no field {p.name!r} of type {p.type}")
        for b in body_fields:
            f = s.field(b)
            if f is None or f.type != "i32":
                raise DescriptorError(path, "instance", f"struct {s.name} needs an i32 field {b!r}")
        return s
    # vectors first so 16-byte fields need no padding between them
    ordered = [p for p in params if p.type == "vec3"] + [p for p in params if p.type != "vec3"]
    raw = [{"name": p.name, "type": p.type, "doc": p.doc} for p in ordered]
    raw += [{"name": b, "type": "i32"} for b in body_fields]
    align = 16 if any(p.type == "vec3" for p in params) else 4
    return layout(f"{camel(name)}_Force", f"Instance of the {name} force.", align, raw, path, "params")


def load_force(path, structs):
    path = Path(path)
    d, lines = yaml_loader.load_with_lines(path)
    if not isinstance(d, dict):
        raise DescriptorError(path, "(file)", "must be a mapping")
    unknown = unknown_keys(d, TOP_KEYS)
    if unknown:
        raise DescriptorError(path, "(top level)", f"unknown key(s) {unknown}")
    for key in ("name", "kind", "apply"):
        if key not in d:
            raise DescriptorError(path, key, "missing")
    name = d["name"]
    why = naming.problem(name, "force")
    if why or name != name.lower():
        raise DescriptorError(path, "name", f"must be a lower_case identifier, got {name!r}" + (f" ({why})" if why else ""))
    kind = d["kind"]
    if kind not in KINDS:
        raise DescriptorError(path, "kind", f"unknown kind {kind!r} (known: {', '.join(KINDS)})")
    for key in ("symmetric", "world_anchor", "joint"):
        if key in d and not isinstance(d[key], bool):
            raise DescriptorError(path, key, f"must be true or false, got {d[key]!r}")
    if d.get("world_anchor") and kind != "binary":
        raise DescriptorError(path, "world_anchor", "only a binary force can be anchored to the world")
    if d.get("joint") and kind != "binary":
        raise DescriptorError(path, "joint", "only a binary force joins two bodies")
    params = _params(path, d.get("params"), "params", PARAM_KEYS)
    globals_ = _params(path, d.get("globals"), "globals", GLOBAL_KEYS)
    if kind == "global" and params:
        raise DescriptorError(path, "params", "a global force has no per-instance params; use globals")
    names = [p.name for p in params + globals_]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise DescriptorError(path, "params", f"name(s) {sorted(dup)} declared twice")
    holds = d.get("holds_points")
    if holds is not None:
        vec3s = [p.name for p in params if p.type == "vec3"]
        if not d.get("joint"):
            raise DescriptorError(path, "holds_points", "only a joint (joint: true) holds points together")
        if not (isinstance(holds, list) and len(holds) == 2 and all(h in vec3s for h in holds) and holds[0] != holds[1]):
            raise DescriptorError(path, "holds_points", f"must name two different vec3 params (a's point, then b's) "
                                  f"of {vec3s}, got {holds!r}")
    instance = _instance_struct(path, d, name, kind, params, structs)
    force = Force(name, kind, d.get("doc", ""), d.get("symmetric", False), d.get("world_anchor", False),
                  d.get("joint", False), params, globals_, instance, str(path), holds_points=tuple(holds or ()))
    variants = {"global": ["body"], "unary": ["body"], "binary": ["pair"] + (["world"] if force.world_anchor else [])}
    force.kernels = [_build_kernel(force, v, d, lines, path) for v in variants[kind]]
    return force


def _origin(path, lines, field, what):
    """How generated code names a descriptor entry: 'let depth (contact.yaml:27)'."""
    return f"{what} ({Path(path).name}:{lines[field]})"


def _build_kernel(force, variant, d, lines, path):
    ctx = km.Context()
    ctx.h = H
    bodies = [km.Body("a", ctx)] + ([km.Body("b", ctx)] if variant == "pair" else [])
    names = {"a": bodies[0]}
    if force.kind == "binary":
        names["b"] = bodies[1] if variant == "pair" else km.World()
    names["h"] = H  # the step (or substep) size the force is evaluated for
    param_syms = {}
    for src, plist in (("param", force.params), ("global", force.globals)):
        for p in plist:
            # lanes as name__i: user names cannot contain '__', so these cannot collide
            syms = [sp.Symbol(f"{'p' if src == 'param' else 'g'}_{p.name}{'' if p.lanes == 1 else f'__{i}'}", real=True)
                    for i in range(p.lanes)]
            param_syms[p.name] = (src, p, syms)
            names[p.name] = syms[0] if p.lanes == 1 else sp.Matrix(syms)
    let = d.get("let") or {}
    if not isinstance(let, dict):
        raise DescriptorError(path, "let", "must be a mapping of name -> expression")
    # each let becomes opaque symbols; derivatives flow through them by the chain rule
    # (forward mode), which keeps every expression SymPy differentiates short
    lets = []
    for lname, text in let.items():
        why = naming.problem(lname, "let")
        if why or lname in km.FUNCTIONS or lname in names or lname == "h":
            raise DescriptorError(path, f"let.{lname}", why or f"{lname!r} is not a free identifier")
        origin = _origin(path, lines, f"let.{lname}", f"let {lname}")
        ctx.origin = origin
        value = evaluate(text, names, path, f"let.{lname}")
        held = isinstance(value, km.Lagged)
        if held:
            value = value.value
        if isinstance(value, (sp.MatrixBase, sp.Expr)):
            _check_scalars(value, path, f"let.{lname}", text)
        if isinstance(value, sp.MatrixBase) and value.shape[1] == 1:
            syms = [sp.Symbol(f"L_{lname}__{i}", real=True) for i in range(value.rows)]
            names[lname], exprs = sp.Matrix(syms), list(value)
        elif isinstance(value, sp.Expr):
            syms, exprs = [sp.Symbol(f"L_{lname}", real=True)], [value]
            names[lname] = syms[0]
        else:
            raise DescriptorError(path, f"let.{lname}", f"{text!r} is neither a number nor a vector")
        lets.append((list(zip(syms, exprs)), held, origin))
    apply = d["apply"]
    if not isinstance(apply, list) or not apply:
        raise DescriptorError(path, "apply", "must be a non-empty list of force(...), torque(...) or force_at_point(...)")
    F = [sp.zeros(6, 1) for _ in bodies]
    applies = []
    for i, text in enumerate(apply):
        origin = _origin(path, lines, f"apply[{i}]", f"apply[{i}]")
        ctx.origin = origin
        c = evaluate(text, names, path, f"apply[{i}]")
        if not isinstance(c, km.Contribution):
            raise DescriptorError(path, f"apply[{i}]", f"{text!r} is not force(...), torque(...) or force_at_point(...)")
        for vname, v in (("force", c.force), ("torque", c.torque)):
            if not isinstance(v, sp.MatrixBase) or v.shape != (3, 1):
                raise DescriptorError(path, f"apply[{i}]", f"the {vname} in {text!r} is not a 3-vector")
            _check_scalars(v, path, f"apply[{i}]", text)
        if isinstance(c.body, km.World):
            applies.append((origin, None))
            continue
        k = bodies.index(c.body)
        applies.append((origin, k))
        F[k] += sp.Matrix.vstack(c.force, c.torque)
    # values the apply entries' primitives hold through the step (force_at_joint's arm and its share)
    for syms, exprs, origin in ctx.held:
        lets.append((list(zip(syms, exprs)), True, origin))

    zero = {s: 0 for b in bodies for s in b.delta}
    wrt = [z for b in bodies for z in b.delta] + [z for b in bodies for z in b.u]
    # the lets that read the state (the cut) and those that reach it only through them (behind)
    cut, behind = _cut(lets, wrt) or (None, set())
    forces_read = set().union(*[e.free_symbols for e in _entries(F)])
    let_syms = set()
    deriv = {}  # (let symbol, z) -> symbol of its total derivative at delta = 0
    stages = []

    def emit(stage, sym, z, dz):
        dz = dz.xreplace(zero)
        if dz.is_Number or dz.is_Symbol:  # trivial: substitute, emit nothing
            if dz != 0:
                deriv[(sym, z)] = dz
        else:
            deriv[(sym, z)] = sp.Symbol(f"d_{sym.name}__{z.name}", real=True)
            stage.append((deriv[(sym, z)], dz))

    for group, held, origin in lets:
        stage = []
        syms = [sym for sym, _ in group]
        for sym, expr in group:
            stage.append((sym, expr.xreplace(zero)))
            if held:
                continue
            if sym not in behind:
                for z in wrt:
                    emit(stage, sym, z, _total_derivative(expr, z, let_syms, deriv))
                continue
            # behind the cut: its derivatives by the cut's entries, and by the state only
            # where the forces read it, as the cut's chain rule
            for c in cut:
                emit(stage, sym, c, _total_derivative(expr, c, behind, deriv))
            if sym in forces_read:
                for z in wrt:
                    emit(stage, sym, z, sum((deriv[(sym, c)] * deriv[(c, z)] for c in cut
                                             if (sym, c) in deriv and (c, z) in deriv), sp.Integer(0)))
        let_syms.update(syms)
        stages.append(Stage(origin, held, stage))
    kernel = Kernel(force, variant, len(bodies), [], [], pre=ctx.pre,
                    apply_origin=_origin(path, lines, "apply", "apply"), applies=applies)
    for k, b in enumerate(bodies):
        kernel.forces += [e.xreplace(zero) for e in F[k]]
    for i, bi in enumerate(bodies):
        for kind in ("dd", "du"):
            for j, bj in enumerate(bodies):
                zs = bj.delta if kind == "dd" else bj.u
                cols = [[_total_derivative(F[i][r], z, let_syms, deriv).xreplace(zero) for r in range(6)] for z in zs]
                exprs = [e for col in cols for e in col]
                if any(e != 0 for e in exprs):
                    kernel.blocks.append(Block(kind, i, j, exprs))
    kernel.stages = stages
    everything = kernel.forces + [e for blk in kernel.blocks for e in blk.exprs]
    everything_and_lets = everything + [e for st in stages for _, e in st.items]
    for e in everything_and_lets:
        bad = e.atoms(sp.Derivative, sp.Subs, sp.DiracDelta) or e.has(sp.nan, sp.zoo, sp.oo)
        if bad:
            raise DescriptorError(path, "apply", f"the force is not differentiable where it is evaluated ({bad})")
    # inputs: only the symbols the expressions (and the preamble they use) read, in a fixed order
    defined = {sym for st in stages for sym, _ in st.items}
    used = set().union(set(), *[e.free_symbols for e in everything_and_lets]) - defined - {H}
    used_pre = [s for s in ctx.pre if s in used]
    kernel.pre = {s: ctx.pre[s] for s in used_pre}
    kernel.pre_origins = {s: ctx.origins[s] for s in used_pre}
    used = (used - set(used_pre)).union(set(), *[ctx.pre[s].free_symbols for s in used_pre]) - {H}
    # the implicit form multiplies dF/ddelta by the bodies' velocities: they are inputs then
    if any(blk.kind == "dd" for blk in kernel.blocks):
        used |= {s for b in bodies for s in b.u}
    kernel.implicit = _implicit_form(kernel, bodies, ctx)
    if cut is not None:
        kernel.implicit["through_lets"] = _implicit_through_lets(kernel, bodies, ctx, F, forces_read & let_syms,
                                                                 deriv, zero)
    for k, b in enumerate(bodies):
        arms = ctx.arms.get(b.tag, [])
        if len(arms) == 1:
            kernel.joint_arms[k] = list(arms[0][0]) + [arms[0][1]]
    for k, b in enumerate(bodies):
        for fname, syms in b.field_syms.items():
            for lane, s in enumerate(syms):
                if s in used:
                    kernel.inputs.append(Input(s, "body", k, fname, lane))
    for pname, (src, p, syms) in param_syms.items():
        for lane, s in enumerate(syms):
            if s in used:
                kernel.inputs.append(Input(s, src, 0, pname, lane))
    known = {i.symbol for i in kernel.inputs}
    stray = used - known
    if stray:
        raise DescriptorError(path, "apply", f"expression depends on unknown symbols {sorted(map(str, stray))}")
    return kernel


H = sp.Symbol("h", positive=True)


def _check_scalars(value, path, where, text):
    """Every entry must be a number-valued expression (a comparison is only a where() condition)."""
    entries = list(value) if isinstance(value, sp.MatrixBase) else [value]
    for e in entries:
        if not isinstance(e, sp.Expr):
            raise DescriptorError(path, where, f"{text!r} has a non-numeric entry {e} (a comparison belongs "
                                  "in where(condition, a, b))")


def _arc(body, ctx):
    """The second-order part of the step's motion of the one point a joint acts at on this body
    (force_at_joint), as far as the linearisation leaves its swing explicit: (1 - s) h^2/2
    w x (w x r). The linear prediction moves the point along the tangent, h (v + w x r); the
    body's rotation carries it on the arc, and a stiff joint pulls back the difference every step
    (a 1 m pendulum at 60 Hz stretched its joint 1.5 mm, eight times its load, and its period was
    off by 1.5e-3; with the arc 0.2 mm and 1.9e-4). Where the swing is implicit (s -> 1) the
    linearisation holds it already. None for a body with no such point or with several."""
    arms = ctx.arms.get(body.tag, [])
    if len(arms) != 1:
        return None
    arm, s = arms[0]
    return (1 - s) * H * H / 2 * km.cross(body.w, km.cross(body.w, arm))


def _implicit_form(kernel, bodies, ctx):
    """What the implicit step consumes, so one SIMD evaluation does the products:
    g_i = F_i + h sum_j dF_i/ddelta_j (u_j + arc_j) and K_ij = h dF_i/du_j + h^2 dF_i/ddelta_j,
    where arc_j (_arc) displaces body j by the arc of the point a joint acts at on it."""
    def block(kind, i, j):
        for b in kernel.blocks:
            if (b.kind, b.row_body, b.col_body) == (kind, i, j):
                return sp.Matrix(6, 6, lambda r, c: b.exprs[6 * c + r])
        return None
    g, pairs, K = [], [], []
    for i in range(len(bodies)):
        gi = sp.Matrix(kernel.forces[6 * i:6 * i + 6])
        for j, bj in enumerate(bodies):
            J = block("dd", i, j)
            if J is not None:
                gi += H * J * sp.Matrix(bj.u)
                arc = _arc(bj, ctx)
                if arc is not None:
                    gi += J[:, 0:3] * arc
        g += list(gi)
    for i in range(len(bodies)):
        for j in range(len(bodies)):
            Jd, Ju = block("dd", i, j), block("du", i, j)
            if Jd is None and Ju is None:
                continue
            Kij = sp.zeros(6, 6)
            if Ju is not None:
                Kij += H * Ju
            if Jd is not None:
                Kij += H * H * Jd
            pairs.append((i, j))
            K += [Kij[r, c] for c in range(6) for r in range(6)]
    return {"outputs": g + K, "pairs": pairs}


def _implicit_through_lets(kernel, bodies, ctx, F, reads, deriv, zero):
    """The implicit form again, its products taken on the lets the forces read rather than on
    the forces' 6-vectors: a contact's force f acts on a as -f and on b as f at lever arms the
    step holds, so h df/du + h^2 df/ddelta is formed once per body and column (3 entries) and
    each 6x6 block is its sign and lever arm's cross product of it. Likewise g's dF/ddelta
    (u h + arc) as df/ddelta (u h + arc) once. The same outputs in the same order as
    _implicit_form; the kernel emits whichever costs fewer operations. reads: the lets F reads."""
    lets, comb, drift = [], {}, {}
    read = sorted((s for s in reads if any(k[0] == s for k in deriv)), key=lambda s: s.name)

    def named(name, expr):
        if expr.is_Number or expr.is_Symbol:
            return expr
        sym = sp.Symbol(name, real=True)
        lets.append((sym, expr))
        return sym

    steps = []
    for j, bj in enumerate(bodies):
        arc = _arc(bj, ctx)
        steps.append([H * u + (arc[c] if arc is not None and c < 3 else 0) for c, u in enumerate(bj.u)])
    for s in read:
        drift[s] = named(f"kg_{s.name}", sum((deriv.get((s, z), 0) * steps[j][c] for j, bj in enumerate(bodies)
                                              for c, z in enumerate(bj.delta)), sp.Integer(0)))
        for j, bj in enumerate(bodies):
            for c in range(6):
                comb[(s, j, c)] = named(f"kk_{s.name}__{'ab'[j]}{c}",
                                        H * deriv.get((s, bj.u[c]), 0) + H * H * deriv.get((s, bj.delta[c]), 0))
    g = []
    for i in range(len(bodies)):
        for r in range(6):
            e = F[i][r]
            gi = e + sum((sp.diff(e, z) * steps[j][c] for j, bj in enumerate(bodies) for c, z in enumerate(bj.delta)),
                         sp.Integer(0)) + sum((sp.diff(e, s) * drift[s] for s in read), sp.Integer(0))
            g.append(gi.xreplace(zero))
    K = []
    for i, j in kernel.implicit["pairs"]:
        bj = bodies[j]
        for c in range(6):
            for r in range(6):
                e = F[i][r]
                k = H * sp.diff(e, bj.u[c]) + H * H * sp.diff(e, bj.delta[c]) + \
                    sum((sp.diff(e, s) * comb[(s, j, c)] for s in read), sp.Integer(0))
                K.append(k.xreplace(zero))
    return {"lets": lets, "outputs": g + K}


def _entries(F):
    """Every body's force and torque entries, in one list."""
    return [e for Fk in F for e in Fk]


def _cut(lets, wrt):
    """(cut, behind): the entries of the lets that read the state directly, when the rest of the
    force reaches the state only through them and they are fewer than the state's variables, and
    the symbols of the lets that reach it only through them; else None.
    Behind such a cut (a contact's relative displacement and velocity: 6 entries, where a pair
    has 24 variables) each later let is differentiated by the cut's entries alone, and the
    forces' lets are brought back to the state by the chain rule once."""
    zs = set(wrt)
    cut, behind = [], set()
    for group, held, _ in lets:
        if held:
            continue
        reads = set().union(*[e.free_symbols for _, e in group])
        if reads & zs:
            if reads & behind:  # a let reading the state beside a later one: no single cut
                return None
            cut += [sym for sym, _ in group]
        elif reads & (behind | set(cut)):
            behind.update(sym for sym, _ in group)
    return (cut, behind) if behind and len(cut) < len(wrt) else None


def _total_derivative(expr, z, let_syms, deriv):
    """d expr / dz through the let symbols it references (chain rule on their known derivatives)."""
    out = sp.diff(expr, z)
    for s in expr.free_symbols & let_syms:
        ds = deriv.get((s, z))
        if ds is not None:
            out += sp.diff(expr, s) * ds
    return out


def load_forces(directories, structs):
    forces, seen = [], {}
    by_name = {s.name: s for s in structs}
    for directory in directories:
        for p in sorted(Path(directory).glob("*.yaml")):
            f = load_force(p, by_name)
            if f.name in seen:
                raise DescriptorError(p, "name", f"force {f.name!r} is also declared in {seen[f.name]}")
            seen[f.name] = str(p)
            forces.append(f)
    return forces


def scene_setting(force, name):
    """Where global `name` of `force` sits under a scene's settings: one named like its force at
    the top (gravity), <force>_<key> at <force>.<key> (contact.slop), any other at <force>.<name>."""
    if name == force:
        return name
    return f"{force}.{name[len(force) + 1:] if name.startswith(force + '_') else name}"


def island_globals(forces):
    """Every force's globals, merged into one Island_Params block (same name must mean the same),
    each with its scene setting (that of the first force declaring it)."""
    out, origin, settings = [], {}, {}
    for f in forces:
        for g in f.globals:
            if g.name in origin:
                prev = origin[g.name]
                if (prev[1].type, prev[1].default, prev[1].min, prev[1].min_exclusive, prev[2]) != \
                        (g.type, g.default, g.min, g.min_exclusive, g.setting):
                    raise DescriptorError(f.source, f"globals.{g.name}",
                                          f"also declared differently by {prev[0]}")
                g.setting = prev[1].setting
                continue
            declared = g.setting
            g.setting = declared or scene_setting(f.name, g.name)
            for other, who in settings.items():
                if other == g.setting or other.startswith(g.setting + ".") or g.setting.startswith(other + "."):
                    raise DescriptorError(f.source, f"globals.{g.name}", f"its scene setting settings.{g.setting} "
                                          f"collides with settings.{other} of global {who}")
            settings[g.setting] = g.name
            origin[g.name] = (f.source, g, declared)
            out.append(g)
    return out

"""Kinematic primitives the force descriptors are written in.

A body's pose is perturbed as x <- x + dx, R <- exp([dth]x) R. Every Jacobian is taken at
dx = dth = 0, so the first-order rotation (I + [dth]x) gives exact first derivatives; the
perturbation symbols are substituted by zero after differentiation.

Quantities that depend neither on the perturbation nor on the velocities (R r, R I R^T,
p - x) become opaque symbols computed once in the kernel's preamble: SymPy then
differentiates short expressions, and the emitted code shares them.
"""
import sympy as sp


def vec(*xs):
    for x in xs:
        if not isinstance(sp.sympify(x), sp.Expr):
            raise TypeError(f"vec() entries must be numbers, not {x} (a comparison belongs in where(...))")
    return sp.Matrix(xs)


def cross(a, b):
    return a.cross(b)


def dot(a, b):
    return (a.T * b)[0, 0]


def norm(a):
    return sp.sqrt(dot(a, a))


def where(cond, x, y):
    return sp.Piecewise((x, cond), (y, True))


def positive_part(x):
    return sp.Piecewise((x, x > 0), (0, True))


def skew(w):
    return sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def quat_to_matrix(w, x, y, z):
    return sp.Matrix([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _syms(prefix, names):
    return [sp.Symbol(f"{prefix}_{n}", real=True) for n in names]


class Context:
    """Preamble symbols of one kernel: symbol -> expression of the inputs, in order."""

    def __init__(self):
        self.pre = {}
        self.origin = None  # what the descriptor is evaluating (set by the caller), noted per new symbol
        self.origins = {}
        self._cache = {}
        self.bodies = []  # the kernel's bodies, registered as they are made
        self.h = None  # the step's symbol, set by the caller
        self.held = []  # [(symbols, expressions, origin)]: values primitives hold through the step
        self.arms = {}  # body tag -> [(held arm, held turn share)], one per force_at_joint on it

    def hold(self, name, expr):
        """Symbols for expr's value at the evaluated state, held through the linearisation (as a
        lagged() let): the caller appends them to the kernel's held lets."""
        n = len(self.held)
        if isinstance(expr, sp.MatrixBase):
            syms = [sp.Symbol(f"T{n}_{name}__{i}", real=True) for i in range(expr.rows)]
            self.held.append((syms, list(expr), self.origin))
            return sp.Matrix(syms)
        sym = sp.Symbol(f"T{n}_{name}", real=True)
        self.held.append(([sym], [expr], self.origin))
        return sym

    def at_rest(self, expr):
        """expr at zero pose perturbation of every body: its value at the evaluated state."""
        return expr.xreplace({s: 0 for b in self.bodies for s in b.delta})

    def vector(self, key, name, expr):
        if key not in self._cache:
            syms = [sp.Symbol(f"{name}{len(self._cache)}_{i}", real=True) for i in range(expr.rows)]
            for s_, e in zip(syms, expr):
                self.pre[s_] = e
                self.origins[s_] = self.origin
            self._cache[key] = sp.Matrix(syms)
        return self._cache[key]

    def sym33(self, key, name, M):
        if key not in self._cache:
            idx = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]
            syms = [sp.Symbol(f"{name}{len(self._cache)}_{r}{c}", real=True) for r, c in idx]
            for s_, (r, c) in zip(syms, idx):
                self.pre[s_] = M[r, c]
                self.origins[s_] = self.origin
            a, b, c_, d, e, f = syms
            self._cache[key] = sp.Matrix([[a, d, e], [d, b, f], [e, f, c_]])
        return self._cache[key]


class Body:
    """Symbols of one body's state, its mass parameters and its pose perturbation."""

    # field of the packed Rigid_Body -> (symbol suffixes, stored lanes used)
    FIELDS = {
        "position": ["px", "py", "pz"],
        "orientation": ["qw", "qx", "qy", "qz"],
        "velocity": ["vx", "vy", "vz"],
        "angular_velocity": ["wx", "wy", "wz"],
        "mass": ["m"],
        "inertia_body": ["Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"],
        # the pose at which world-frame contact geometry was measured (the island's start):
        # attached points follow the body from there, whatever state a stage evaluates
        "ref_position": ["rpx", "rpy", "rpz"],
        "ref_orientation": ["rqw", "rqx", "rqy", "rqz"],
    }

    def __init__(self, tag, ctx):
        self.tag, self.ctx = tag, ctx
        ctx.bodies.append(self)
        self.field_syms = {f: _syms(tag, n) for f, n in self.FIELDS.items()}
        self.dx = sp.Matrix(_syms(tag, ["dx", "dy", "dz"]))
        self.dth = sp.Matrix(_syms(tag, ["dtx", "dty", "dtz"]))
        self.x0 = sp.Matrix(self.field_syms["position"])
        self.q = self.field_syms["orientation"]
        self.v = sp.Matrix(self.field_syms["velocity"])
        self.w = sp.Matrix(self.field_syms["angular_velocity"])
        self.mass = self.field_syms["mass"][0]
        Ixx, Iyy, Izz, Ixy, Ixz, Iyz = self.field_syms["inertia_body"]
        self.inertia_body = sp.Matrix([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])
        self.R = quat_to_matrix(*self.q)
        self.x = self.x0 + self.dx

    @property
    def delta(self):
        return list(self.dx) + list(self.dth)

    @property
    def u(self):
        return list(self.v) + list(self.w)

    def rotate_perturbed(self, y):
        return y + cross(self.dth, y)

    def body_to_world(self, r):
        """R r as preamble symbols (r in body coordinates)."""
        return self.ctx.vector(("R", self.tag, tuple(r)), f"{self.tag}_r", self.R * r)

    def offset_of(self, p):
        """Where the material point that was at world p (at the reference pose) is now, relative
        to the centre of mass: R R_ref^T (p - x_ref), as preamble symbols."""
        x_ref = sp.Matrix(self.field_syms["ref_position"])
        R_ref = quat_to_matrix(*self.field_syms["ref_orientation"])
        return self.ctx.vector(("off", self.tag, tuple(p)), f"{self.tag}_o", self.R * (R_ref.T * (p - x_ref)))

    def inertia_world(self):
        return self.ctx.sym33(("I", self.tag), f"{self.tag}_Iw", self.R * self.inertia_body * self.R.T)


class World:
    """The fixed world on the b side of a world-anchored binary force."""
    tag = "world"


class Contribution:
    def __init__(self, body, force, torque):
        self.body, self.force, self.torque = body, force, torque


def _need_body(fn, body):
    if not isinstance(body, (Body, World)):
        raise TypeError(f"{fn}() takes a body (a or b) as its first argument")


def world_point(body, r):
    """A point fixed in the body, given in body coordinates (world coordinates for the world)."""
    _need_body("world_point", body)
    if isinstance(body, World):
        return r
    return body.x + body.rotate_perturbed(body.body_to_world(r))


def point_velocity(body, r):
    _need_body("point_velocity", body)
    if isinstance(body, World):
        return sp.zeros(3, 1)
    return body.v + cross(body.w, body.rotate_perturbed(body.body_to_world(r)))


def attached_point(body, p):
    """The material point of the body that is at world point p at the start of the step."""
    _need_body("attached_point", body)
    if isinstance(body, World):
        return p
    return body.x + body.rotate_perturbed(body.offset_of(p))


def attached_velocity(body, p):
    _need_body("attached_velocity", body)
    if isinstance(body, World):
        return sp.zeros(3, 1)
    return body.v + cross(body.w, body.rotate_perturbed(body.offset_of(p)))


def inertia_world(body):
    _need_body("inertia_world", body)
    if isinstance(body, World):
        raise TypeError("inertia_world() of the world is undefined")
    # (I + [dth]x) Iw (I + [dth]x)^T: the first-order change of R I R^T under the perturbation
    Iw = body.inertia_world()
    P = sp.eye(3) + skew(body.dth)
    return P * Iw * P.T


def force(body, f):
    _need_body("force", body)
    return Contribution(body, f, sp.zeros(3, 1))


def torque(body, t):
    _need_body("torque", body)
    return Contribution(body, sp.zeros(3, 1), t)


class Lagged:
    """A value taken at the start of the step and held constant by the linearisation."""

    def __init__(self, value):
        self.value = value


def lagged(x):
    """x at the start of the step, with zero derivatives (e.g. friction's regularised
    slip speed: holding it makes the linearised friction a damper that cannot overshoot)."""
    return Lagged(x)


def attached_offset(body, p):
    """Lever arm of the material point that was at world p, held fixed through the step:
    a contact force acts at the contact, which does not turn with the body within a step."""
    _need_body("attached_offset", body)
    if isinstance(body, World):
        return sp.zeros(3, 1)
    return body.offset_of(p)


def velocity_at_offset(body, r):
    """Velocity of the body at lever arm r (world frame) from its centre of mass: v + w x r.
    With r held (attached_offset), this is the velocity at a contact that stays put while the
    body turns under it, not that of a material point swinging away with the body."""
    _need_body("velocity_at_offset", body)
    if isinstance(body, World):
        return sp.zeros(3, 1)
    return body.v + cross(body.w, r)


def force_at_offset(body, r, f):
    """A force f applied at lever arm r from the centre of mass: (f, r x f)."""
    _need_body("force_at_offset", body)
    if isinstance(body, World):
        return Contribution(body, f, sp.zeros(3, 1))
    return Contribution(body, f, cross(r, f))


def turn_share(body, arm, f):
    """How much of a lever arm's turn the linearisation keeps: s = q^2 / (1 + q^2) with
    q = h^2 |f| |r| / (I_lo + mu |r|^2): (h times) the frequency, squared, at which a force f at
    arm r swings the body about the point it acts at. I_lo <= the body's least principal moment;
    mu is the pair's reduced mass m_a m_b / (m_a + m_b), the body's own mass against the world:
    against a light partner the point is free and the body turns about its centre, against the
    world or a heavy partner about the point.

    The turn of the arm under a force is geometric stiffness: the term that, implicit, holds a
    light link in a chain under a heavy load (q >> 1 there: held, the link's swing about its joint
    is explicit and diverges), and that, implicit, also damps every swing: a pendulum on a stiff
    joint at 60 Hz keeps 6% of its energy after 5 s with it and 102% without it (q ~ 0.05).
    With s the part left explicit, (1 - s) q = q / (1 + q^2) <= 1/2, stays inside the explicit
    step's stability bound (4) whatever the step, the load and the masses."""
    I = body.inertia_body
    tr = I.trace()
    i_lo = 4 * I.det() / sp.Max(tr * tr, sp.Float(1e-30))  # abc / ((a+b+c)/2)^2 <= a for a <= b <= c
    others = [b for b in body.ctx.bodies if b is not body]
    mu = body.mass if not others else body.mass * others[0].mass / sp.Max(body.mass + others[0].mass, sp.Float(1e-30))
    r2 = dot(arm, arm)
    h = body.ctx.h
    q = h * h * sp.sqrt(dot(f, f) * r2) / sp.Max(i_lo + mu * r2, sp.Float(1e-30))
    return 1 - 1 / (1 + q * q)


def force_at_point(body, p, f):
    """A force f applied at world point p: generalised force (f, (p - com) x f)."""
    _need_body("force_at_point", body)
    if isinstance(body, World):
        return Contribution(body, f, sp.zeros(3, 1))
    return Contribution(body, f, cross(p - body.x, f))


def force_at_joint(body, p, f):
    """A joint's force f at world point p, a point of the body: (f, (p - com) x f) as with
    force_at_point, but the lever arm's turn within the step enters the linearisation by
    turn_share(): r = r0 + s (r - r0), with r0 and s held at the evaluated state (the value is
    exact; the Jacobian keeps s of the arm's turn). The implicit form also moves the point along
    its arc (forces._arc)."""
    _need_body("force_at_joint", body)
    if isinstance(body, World):
        return Contribution(body, f, sp.zeros(3, 1))
    ctx = body.ctx
    arm = p - body.x
    arm0 = ctx.hold("arm", ctx.at_rest(arm))
    s = ctx.hold("turn", turn_share(body, arm0, ctx.at_rest(f)))
    ctx.arms.setdefault(body.tag, []).append((arm0, s))
    return Contribution(body, f, cross(arm0 + s * (arm - arm0), f))


def world_axis(body, d):
    """A direction fixed in the body, given in body coordinates (world coordinates for the
    world): R d, turning with the body's perturbation. Not normalised."""
    _need_body("world_axis", body)
    if isinstance(body, World):
        return d
    return body.rotate_perturbed(body.body_to_world(d))


def mass_of(body):
    """The body's mass; 0 for the world (so max(mass_of(a), mass_of(b)) is the heavier body)."""
    _need_body("mass_of", body)
    return sp.Integer(0) if isinstance(body, World) else body.mass


def moment_of(body):
    """Half the trace of the body's inertia: no principal moment is larger (each is at most the
    sum of the other two). 0 for the world. A rotation-invariant scale for angular stiffness."""
    _need_body("moment_of", body)
    if isinstance(body, World):
        return sp.Integer(0)
    return body.inertia_body.trace() / 2


def inertia_about(body, n):
    """n . I n: the body's moment of inertia about world direction n (unit); 0 for the world."""
    _need_body("inertia_about", body)
    if isinstance(body, World):
        return sp.Integer(0)
    return dot(n, inertia_world(body) * n)


def stop_inertia(a, b, n, alone=None):
    """The moment a joint's angular term about world direction n (unit) is tuned to: a's and
    b's moments about n in series, raised toward the heavier's but to at most 16 times the
    series moment (the term at most four times the joint's frequency on the lighter body). To
    the world, a's moment about n, or `alone` when given. Tuned to the heavier body alone, a
    limit or alignment stopping a light limb's turn about its length flings it (docs/joints.md)."""
    if not isinstance(a, (Body, World)) or not isinstance(b, (Body, World)):
        raise TypeError("stop_inertia() takes two bodies (a, b) as its first two arguments")
    ia = inertia_about(a, n)
    if isinstance(b, World):
        return ia if alone is None else alone
    ib = inertia_about(b, n)
    return where(ib > 0, sp.Min(sp.Max(ia, ib), 16 * (ia * ib) / sp.Max(ia + ib, sp.Float(1.0e-30))),
                 ia if alone is None else alone)


def angular_velocity(body):
    """The body's angular velocity (world frame); zero for the world."""
    _need_body("angular_velocity", body)
    return sp.zeros(3, 1) if isinstance(body, World) else body.w


FUNCTIONS = {
    "vec": vec, "dot": dot, "cross": cross, "norm": norm, "sqrt": sp.sqrt, "abs": sp.Abs,
    "where": where, "positive_part": positive_part, "min": sp.Min, "max": sp.Max,
    "world_point": world_point, "point_velocity": point_velocity,
    "attached_point": attached_point, "attached_velocity": attached_velocity,
    "inertia_world": inertia_world, "force": force, "torque": torque,
    "force_at_point": force_at_point, "force_at_joint": force_at_joint, "force_at_offset": force_at_offset,
    "attached_offset": attached_offset, "velocity_at_offset": velocity_at_offset, "lagged": lagged,
    "world_axis": world_axis, "mass_of": mass_of, "moment_of": moment_of, "inertia_about": inertia_about,
    "stop_inertia": stop_inertia,
    "angular_velocity": angular_velocity,
    "atan2": sp.atan2,
}

# attributes a descriptor may read from a body
BODY_ATTRIBUTES = {"x": "x", "v": "v", "w": "w", "mass": "mass"}

#!/usr/bin/python3
"""Writes the built-in scene files (examples/scenes/*.json). Deterministic, standard library only.

    /usr/bin/python3 examples/scenes/make_scenes.py [--out DIR]
    /usr/bin/python3 examples/scenes/make_scenes.py --bench [--out DIR]   # the benchmark worlds

pile65 mirrors testing/scenes.cpp pile_in_bin(w, 65, 0.25, seed 1): the same Mersenne
Twister draws, in the same order, with float32 rounding, so the file is the fixture's scene.
world1000 is a sparse world of 1,000 bodies in the manner of sparse_world(w, 1000, 100, 1)
(its hulls are point-symmetric clouds, so their centre of mass is their origin and the file
needs no hull arithmetic). The small scenes are written out by hand below. The benchmark
worlds (BENCH_SCENES: Box3D's large pyramid and many pyramids, a 100,000-body sparse world to
measure asleep, a bin of 400 balls) are written to build/bench-scenes (--bench; scripts/bench
does it): the large ones are too big to keep in the tree.
"""
import argparse
import json
import math
import os
import struct


def f32(x):
    return struct.unpack("f", struct.pack("f", x))[0]


class MT19937:
    """std::mt19937, bit for bit."""

    def __init__(self, seed):
        self.mt = [0] * 624
        self.mt[0] = seed & 0xFFFFFFFF
        for i in range(1, 624):
            self.mt[i] = (1812433253 * (self.mt[i - 1] ^ (self.mt[i - 1] >> 30)) + i) & 0xFFFFFFFF
        self.index = 624

    def __call__(self):
        if self.index >= 624:
            for i in range(624):
                y = (self.mt[i] & 0x80000000) | (self.mt[(i + 1) % 624] & 0x7FFFFFFF)
                v = self.mt[(i + 397) % 624] ^ (y >> 1)
                if y & 1:
                    v ^= 0x9908B0DF
                self.mt[i] = v
            self.index = 0
        y = self.mt[self.index]
        self.index += 1
        y ^= y >> 11
        y ^= (y << 7) & 0x9D2C5680
        y ^= (y << 15) & 0xEFC60000
        y ^= y >> 18
        return y & 0xFFFFFFFF


class Rng:
    """testing/scenes.cpp Rng: uniform in [lo, hi) from the top 24 bits of one draw, in float."""

    def __init__(self, seed):
        self.g = MT19937(seed)

    def uniform(self, lo, hi):
        lo, hi = f32(lo), f32(hi)
        x = float(self.g() >> 8)
        return f32(lo + f32(f32(f32(hi - lo) * x) * f32(1.0 / 16777216.0)))


def axis_angle(ax, ay, az, angle):
    s = f32(math.sin(f32(0.5 * angle)))
    return [f32(math.cos(f32(0.5 * angle))), f32(ax * s), f32(ay * s), f32(az * s)]


def quat_mul(a, b):
    return [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]


def random_small_rotation(r, max_angle):
    while True:
        a = [r.uniform(-1, 1) for _ in range(3)]
        n2 = f32(f32(f32(a[0] * a[0]) + f32(a[1] * a[1])) + f32(a[2] * a[2]))
        if not (n2 < 1e-4 or n2 > 1.0):
            break
    n = f32(math.sqrt(n2))
    return axis_angle(f32(a[0] / n), f32(a[1] / n), f32(a[2] / n), r.uniform(-max_angle, max_angle))


def num(x):
    """A float32 as its shortest decimal form (what the C++ reader rounds back to the same float)."""
    x = f32(x)
    if x == 0:
        return 0.0
    for digits in range(1, 10):
        s = "%.*g" % (digits, x)
        if f32(float(s)) == x:
            return float(s)
    return x


def vec(v):
    return [num(x) for x in v]


GROUND = {"name": "ground", "type": "plane", "normal": [0, 0, 1], "offset": 0}


def ground_body(friction=0.5):
    return {"id": "ground", "shape": "ground", "static": True, "friction": friction}


# ---- pile65: the reference design's 65-box group ----


def pile(n=65, h=0.25, seed=1, mass=1.0):
    r = Rng(seed)
    k = max(4, int(math.ceil(4.0 * math.sqrt(n / 65.0))))
    hb = f32(f32(f32(1.2 * (k - 1)) + f32(1.4)) * h)
    wall_t, wall_h = h, f32(4.0 * h)
    spacing, layer = f32(2.4 * h), f32(2.6 * h)
    bodies = []
    for i in range(n):
        col, lay = i % (k * k), i // (k * k)
        jx = f32(r.uniform(-0.1, 0.1) * h)
        jy = f32(r.uniform(-0.1, 0.1) * h)
        x = f32(f32(f32(col % k) - f32(0.5 * (k - 1))) * spacing) + jx
        y = f32(f32(f32(col // k) - f32(0.5 * (k - 1))) * spacing) + jy
        z = f32(f32(1.3 * h) + f32(lay * layer))
        q = random_small_rotation(r, 0.15)
        bodies.append({"id": "box%02d" % i, "shape": "box", "mass": mass, "position": vec([x, y, z]),
                       "orientation": vec(q), "friction": 0.5})
    bodies.insert(0, ground_body())
    wx = [hb + 2 * wall_t, wall_t, wall_h]
    wy = [wall_t, hb, wall_h]
    for s in (-1, 1):
        side = "south" if s < 0 else "north"
        bodies.append({"id": "wall_" + side, "shape": "wall_x", "static": True,
                       "position": vec([0, s * (hb + wall_t), wall_h]), "friction": 0.5})
        side = "west" if s < 0 else "east"
        bodies.append({"id": "wall_" + side, "shape": "wall_y", "static": True,
                       "position": vec([s * (hb + wall_t), 0, wall_h]), "friction": 0.5})
    return {
        "description": "The reference design's 65-box group: 65 boxes (0.25 m half-extent, 1 kg) dropped into a bin "
                       "(ground plane and 4 static walls); about 400 contacts once settled.",
        "settings": {"dt": num(1 / 60), "integrator": "implicit_split", "solver": "cgs"},
        "shapes": [GROUND, {"name": "box", "type": "box", "half_extents": [h, h, h]},
                   {"name": "wall_x", "type": "box", "half_extents": vec(wx)},
                   {"name": "wall_y", "type": "box", "half_extents": vec(wy)}],
        "bodies": bodies,
    }


# ---- world1000: a sparsely populated world ----


def sparse(n=1000, area=100.0, seed=1):
    r = Rng(seed)
    shapes = [GROUND,
              {"name": "box_cube", "type": "box", "half_extents": [1, 1, 1]},
              {"name": "box_slab", "type": "box", "half_extents": [1, 0.7, 0.5]},
              {"name": "box_plank", "type": "box", "half_extents": [1, 0.5, 0.25]},
              {"name": "ball", "type": "sphere", "radius": 1},
              {"name": "capsule_fat", "type": "capsule", "radius": 0.5, "half_height": 0.8},
              {"name": "capsule_thin", "type": "capsule", "radius": 0.35, "half_height": 1.0}]
    boxes = shapes[1:4]
    capsules = shapes[5:7]
    hulls = []
    for k in range(3):
        half = [[r.uniform(-1, 1) for _ in range(3)] for _ in range(6)]
        pts = [vec(p) for p in half] + [vec([-c for c in p]) for p in half]  # point-symmetric: centroid at 0
        hull = {"name": "rock%d" % k, "type": "hull", "points": pts}
        shapes.append(hull)
        hulls.append(hull)
    cells = max(1, int(math.ceil(math.sqrt(n))))
    cell = area / cells
    jitter = max(0.0, 0.5 * cell - 0.6)
    bodies = [ground_body()]
    count = 0
    for k in range(cells * cells):
        if count >= n:
            break
        cx = -0.5 * area + (k % cells + 0.5) * cell + r.uniform(-jitter, jitter)
        cy = -0.5 * area + (k // cells + 0.5) * cell + r.uniform(-jitter, jitter)
        size = r.uniform(0.15, 0.4)
        kind = r.uniform(0, 1)
        dropped = r.uniform(0, 1) < 0.5
        drop = r.uniform(0.05, 0.5) if dropped else 0.0
        yaw = r.uniform(-3.14159, 3.14159)
        density = r.uniform(400, 900)
        q_yaw = axis_angle(0, 0, 1, yaw)

        def body(shape, scale, z, q):
            nonlocal count
            count += 1
            return {"id": count, "shape": shape, "scale": num(scale), "density": num(density),
                    "position": vec([cx, cy, z]), "orientation": vec(q), "friction": 0.5}

        pair = k % 10 == 5 and count + 2 <= n
        if pair or kind < 0.4:
            shape = boxes[0] if pair else boxes[int(r.uniform(0, 2.999))]
            hz = shape["half_extents"][2] * size
            bodies.append(body(shape["name"], size, (0.0 if pair else drop) + hz, q_yaw))
            if pair:  # a smaller box resting on top, turned a little: a two-body island
                top = 0.8 * size
                bodies.append(body(shape["name"], top, 2 * hz + shape["half_extents"][2] * top,
                                   axis_angle(0, 0, 1, yaw + 0.3)))
        elif kind < 0.65:
            bodies.append(body("ball", size, drop + size, q_yaw))
        elif kind < 0.9:  # lying on its side: body z turned horizontal, then yawed
            shape = capsules[int(r.uniform(0, 1.999))]
            q = quat_mul(q_yaw, axis_angle(0, 1, 0, 1.5707963))
            bodies.append(body(shape["name"], size, drop + shape["radius"] * size, q))
        else:  # hulls are dropped a little, at an arbitrary yaw
            hull = hulls[int(r.uniform(0, 2.999))]
            lowest = min(p[2] for p in hull["points"])  # yaw keeps z
            bodies.append(body(hull["name"], size, 0.05 + drop - lowest * size, q_yaw))
    return {
        "description": "The default world: 1,000 boxes, spheres, capsules and hulls scattered over a "
                       "100 m square of ground; half dropped, half resting, most soon asleep.",
        "settings": {"dt": num(1 / 60), "integrator": "implicit_split", "solver": "cgs", "sleeping": True},
        "shapes": shapes,
        "bodies": bodies,
    }


# ---- the small scenes ----


def stack10():
    h = 0.25
    bodies = [ground_body()]
    for i in range(10):
        bodies.append({"id": "box%d" % i, "shape": "box", "mass": 1.0,
                       "position": vec([0, 0, h + i * 2 * h]), "friction": 0.5})
    return {"description": "Ten 1 kg boxes (0.25 m half-extent) stacked touching on the ground: should stand still.",
            "settings": {"dt": num(1 / 60)},
            "shapes": [GROUND, {"name": "box", "type": "box", "half_extents": [h, h, h]}],
            "bodies": bodies}


def chain_ratio(links=20, heavy=1000.0, height=3.0):
    r, half_length, gap = 0.05, 0.2, 0.05
    reach = half_length + 0.5 * gap
    q = vec(axis_angle(0, 1, 0, 1.5707963))  # body z along world +x
    bodies, forces = [], []
    for i in range(links):
        bodies.append({"id": "link%02d" % i, "shape": "link", "mass": heavy if i == links - 1 else 1.0,
                       "position": vec([reach + i * 2 * reach, 0, height]), "orientation": q})
    k = 1e5 * heavy
    c = 2 * math.sqrt(k * 1.0)
    forces.append({"type": "point_to_point", "a": "link00", "b": "world", "point_a": vec([0, 0, -reach]),
                   "point_b": vec([0, 0, height]), "stiffness": num(k), "damping": num(c)})
    for i in range(links - 1):
        forces.append({"type": "point_to_point", "a": "link%02d" % i, "b": "link%02d" % (i + 1),
                       "point_a": vec([0, 0, reach]), "point_b": vec([0, 0, -reach]),
                       "stiffness": num(k), "damping": num(c)})
    return {"description": "A 20-link chain pinned at one end, last link 1000x heavier, point_to_point joints: "
                           "a stiff, badly conditioned system released horizontally.",
            "settings": {"dt": num(1 / 60), "sleeping": False},
            "shapes": [{"name": "link", "type": "capsule", "radius": r, "half_height": num(half_length - r)}],
            "bodies": bodies, "forces": forces}


def spin():
    return {"description": "Intermediate-axis rotation: a 0.1 x 0.4 x 0.8 m box spinning at (1, 10, 1) rad/s "
                           "with no gravity tumbles while |L| and energy hold.",
            "settings": {"dt": num(1 / 60), "gravity": [0, 0, 0], "sleeping": False},
            "shapes": [{"name": "brick", "type": "box", "half_extents": [0.05, 0.2, 0.4]}],
            "bodies": [{"id": "brick", "shape": "brick", "mass": 1.0, "angular_velocity": [1, 10, 1]}]}


def stiff_spring():
    return {"description": "A 1 kg ball on an undamped 1e6 N/m spring to a fixed point (period 6 ms at 60 Hz "
                           "steps): explicit integrators blow up, implicit ones stay bounded.",
            "settings": {"dt": num(1 / 60), "sleeping": False},
            "shapes": [{"name": "ball", "type": "sphere", "radius": 0.1}],
            "bodies": [{"id": "ball", "shape": "ball", "mass": 1.0, "position": [0, 0, 0.9]}],
            "forces": [{"type": "spring", "a": "ball", "b": "world", "point_a": [0, 0, 0], "point_b": [0, 0, 2],
                        "stiffness": 1e6, "damping": 0, "rest_length": 1.0}]}


def incline():
    angle = math.radians(30)
    n = [math.sin(angle), 0, math.cos(angle)]
    down = [math.cos(angle), 0, -math.sin(angle)]
    q = vec(axis_angle(0, 1, 0, angle))
    h = 0.25

    def at(along, side, height):
        return vec([along * down[k] + height * n[k] + (side if k == 1 else 0) for k in range(3)])

    return {"description": "A 30 degree incline: a box with friction 0.8 holds (0.8 > tan 30), one with 0.2 "
                           "slides at g (sin - 0.2 cos), a ball rolls.",
            "settings": {"dt": num(1 / 240), "sleeping": False},
            "shapes": [{"name": "slope", "type": "plane", "normal": vec(n), "offset": 0},
                       {"name": "box", "type": "box", "half_extents": [h, h, h]},
                       {"name": "ball", "type": "sphere", "radius": 0.2}],
            "bodies": [{"id": "slope", "shape": "slope", "static": True, "friction": 1.0},
                       {"id": "sticky", "shape": "box", "mass": 1.0, "position": at(0, -1, h), "orientation": q,
                        "friction": 0.8},
                       {"id": "slippery", "shape": "box", "mass": 1.0, "position": at(0, 0, h), "orientation": q,
                        "friction": 0.2},
                       {"id": "ball", "shape": "ball", "mass": 1.0, "position": at(0, 1, 0.2), "friction": 0.8}]}


def pendulum():
    theta = math.radians(60)
    L = 1.0
    pos = [L * math.sin(theta), 0, 2 - L * math.cos(theta)]
    return {"description": "A 1 m pendulum (1 kg ball on a stiff point-to-point joint to a fixed point) "
                           "released at 60 degrees: period about 2.15 s.",
            "settings": {"dt": num(1 / 120), "sleeping": False},
            "shapes": [{"name": "bob", "type": "sphere", "radius": 0.05}],
            "bodies": [{"id": "bob", "shape": "bob", "mass": 1.0, "position": vec(pos),
                        "orientation": vec(axis_angle(0, 1, 0, -theta))}],
            "forces": [{"type": "point_to_point", "a": "bob", "b": "world", "point_a": [0, 0, L],
                        "point_b": [0, 0, 2], "stiffness": 1e5, "damping": 20}]}


def newton_cradle(n=5, r=0.1, L=1.0):
    theta = math.radians(30)
    bodies, forces = [], []
    for i in range(n):
        ax = i * 2 * r
        if i == 0:
            pos = [ax - L * math.sin(theta), 0, 2 - L * math.cos(theta)]
            q = axis_angle(0, 1, 0, theta)
        else:
            pos, q = [ax, 0, 2 - L], [1, 0, 0, 0]
        bodies.append({"id": "ball%d" % i, "shape": "ball", "mass": 1.0, "position": vec(pos), "orientation": vec(q),
                       "friction": 0.0})
        forces.append({"type": "point_to_point", "a": "ball%d" % i, "b": "world", "point_a": [0, 0, L],
                       "point_b": vec([ax, 0, 2]), "stiffness": 1e5, "damping": 20})
    return {"description": "Newton's cradle: five touching 1 kg balls on 1 m pendulums, the first released "
                           "from 30 degrees (fixed-stiffness contacts, 1e6 N/m, so the transfer is soft).",
            "settings": {"dt": num(1 / 240), "sleeping": False,
                         "contact": {"stiffness": 1e6, "damping": 10}},
            "shapes": [{"name": "ball", "type": "sphere", "radius": r}],
            "bodies": bodies, "forces": forces}


# ---- joints: ragdolls, a door and a bridge ----

# testing/ragdoll.cpp's ragdoll: (name, shape, size, centre standing at 1.8 m, mass share)
RAGDOLL_PARTS = [
    ("pelvis", "box", [0.16, 0.10, 0.08], [0, 0, 0.95], 0.14),
    ("chest", "box", [0.18, 0.11, 0.22], [0, 0, 1.25], 0.36),
    ("head", "sphere", [0.11], [0, 0, 1.63], 0.08),
    ("upper_arm_l", "capsule", [0.05, 0.09], [-0.24, 0, 1.28], 0.028),
    ("forearm_l", "capsule", [0.045, 0.105], [-0.24, 0, 0.99], 0.022),
    ("upper_arm_r", "capsule", [0.05, 0.09], [0.24, 0, 1.28], 0.028),
    ("forearm_r", "capsule", [0.045, 0.105], [0.24, 0, 0.99], 0.022),
    ("thigh_l", "capsule", [0.07, 0.14], [-0.09, 0, 0.67], 0.10),
    ("shank_l", "capsule", [0.055, 0.165], [-0.09, 0, 0.24], 0.06),
    ("thigh_r", "capsule", [0.07, 0.14], [0.09, 0, 0.67], 0.10),
    ("shank_r", "capsule", [0.055, 0.165], [0.09, 0, 0.24], 0.06),
]
# (type, a, b, point standing, axis, ref, cone, lower, upper): elbows bend the hand forward (+y),
# knees the foot back
RAGDOLL_JOINTS = [
    ("cone_twist", 0, 1, [0, 0, 1.03], [0, 0, 1], [0, 1, 0], 0.5, -0.35, 0.35),
    ("cone_twist", 1, 2, [0, 0, 1.50], [0, 0, 1], [0, 1, 0], 0.6, -0.8, 0.8),
    ("cone_twist", 1, 3, [-0.24, 0, 1.42], [0, 0, -1], [0, 1, 0], 1.4, -0.8, 0.8),
    ("hinge", 3, 4, [-0.24, 0, 1.14], [1, 0, 0], [0, 0, -1], 0, 0.0, 2.4),
    ("cone_twist", 1, 5, [0.24, 0, 1.42], [0, 0, -1], [0, 1, 0], 1.4, -0.8, 0.8),
    ("hinge", 5, 6, [0.24, 0, 1.14], [1, 0, 0], [0, 0, -1], 0, 0.0, 2.4),
    ("cone_twist", 0, 7, [-0.09, 0, 0.88], [0, 0, -1], [0, 1, 0], 0.9, -0.5, 0.5),
    ("hinge", 7, 8, [-0.09, 0, 0.46], [1, 0, 0], [0, 0, -1], 0, -2.4, 0.0),
    ("cone_twist", 0, 9, [0.09, 0, 0.88], [0, 0, -1], [0, 1, 0], 0.9, -0.5, 0.5),
    ("hinge", 9, 10, [0.09, 0, 0.46], [1, 0, 0], [0, 0, -1], 0, -2.4, 0.0),
]


def rotate(q, v):
    """q v q* for a unit quaternion (w x y z)."""
    w, x, y, z = q
    t = [2 * (y * v[2] - z * v[1]), 2 * (z * v[0] - x * v[2]), 2 * (x * v[1] - y * v[0])]
    return [v[0] + w * t[0] + (y * t[2] - z * t[1]), v[1] + w * t[1] + (z * t[0] - x * t[2]),
            v[2] + w * t[2] + (x * t[1] - y * t[0])]


def ragdoll(tag, height, mass, pelvis, q, shapes, joint_friction=0.5, friction=0.6):
    """testing/ragdoll.cpp add_ragdoll as scene bodies and forces (its shapes added to `shapes`)."""
    s = height / 1.8
    hip = RAGDOLL_PARTS[0][3]
    bodies, forces = [], []
    for name, kind, size, centre, share in RAGDOLL_PARTS:
        shape = "%s_%s" % (tag, name)
        if kind == "box":
            shapes.append({"name": shape, "type": "box", "half_extents": vec([x * s for x in size])})
        elif kind == "sphere":
            shapes.append({"name": shape, "type": "sphere", "radius": num(size[0] * s)})
        else:
            shapes.append({"name": shape, "type": "capsule", "radius": num(size[0] * s), "half_height": num(size[1] * s)})
        turned = rotate(q, [(centre[k] - hip[k]) * s for k in range(3)])
        bodies.append({"id": shape, "shape": shape, "mass": num(share * mass),
                       "position": vec([pelvis[k] + turned[k] for k in range(3)]), "orientation": vec(q),
                       "friction": num(friction)})
    damper = joint_friction * (mass / 70.0) * s * s
    for kind, a, b, at, axis, ref, cone, lower, upper in RAGDOLL_JOINTS:
        f = {"type": kind, "a": bodies[a]["id"], "b": bodies[b]["id"],
             "point_a": vec([(at[k] - RAGDOLL_PARTS[a][3][k]) * s for k in range(3)]),
             "point_b": vec([(at[k] - RAGDOLL_PARTS[b][3][k]) * s for k in range(3)]),
             "axis_a": axis, "axis_b": axis, "ref_a": ref, "ref_b": ref, "spring_damping": num(damper)}
        if kind == "cone_twist":
            f.update({"cone_angle": num(cone), "twist_lower": num(lower), "twist_upper": num(upper)})
        else:
            f.update({"lower": num(lower), "upper": num(upper)})
        forces.append(f)
    return bodies, forces


def ragdoll_pile(n=8):
    shapes, bodies, forces = [dict(GROUND)], [ground_body(0.6)], []
    for i in range(n):
        # two columns, lying, each crossed at right angles to the one below
        column, level = i % 2, i // 2
        q = quat_mul(axis_angle(0, 0, 1, level * math.pi / 2 + column * 0.3), axis_angle(1, 0, 0, math.pi / 2))
        b, f = ragdoll("doll%d" % i, 1.5 + 0.1 * (i % 4), 50.0 + 10.0 * (i % 4),
                       [1.5 * column - 0.75, 0.05 * level, 0.35 + 0.5 * level], q, shapes)
        bodies += b
        forces += f
    return {"description": "Eight ragdolls (11 bodies each: cone-twist spine, neck, shoulders and hips, hinged elbows "
                           "and knees; 1.5-1.8 m, 50-80 kg) dropped in two crossed piles: they settle in poses their "
                           "joints allow.",
            "settings": {"dt": num(1 / 60), "sleeping": True},
            "shapes": shapes, "bodies": bodies, "forces": forces}


def door_and_bridge(planks=12):
    shapes = [dict(GROUND), {"name": "door", "type": "box", "half_extents": [0.5, 0.02, 1.0]},
              {"name": "plank", "type": "box", "half_extents": [0.25, 0.6, 0.04]},
              {"name": "crate", "type": "box", "half_extents": [0.2, 0.2, 0.2]}]
    bodies = [ground_body(0.6),
              {"id": "door", "shape": "door", "mass": 20.0, "position": [-3.5, -2.0, 1.05], "velocity": [0, 0.75, 0],
               "angular_velocity": [0, 0, 1.5]}]
    forces = [{"type": "hinge", "a": "door", "b": "world", "point_a": [-0.5, 0, 0], "point_b": [-4.0, -2.0, 1.05],
               "axis_a": [0, 0, 1], "axis_b": [0, 0, 1], "ref_a": [1, 0, 0], "ref_b": [1, 0, 0],
               "lower": -1.6, "upper": 1.6, "spring_damping": 2.0}]
    # The bridge: planks 0.5 m long hinged end to end about y, hung in a sag (the i-th turned by a
    # linear share of 0.5 rad) between two world anchors 2 m up.
    length, top = 0.5, 2.0
    tilt = [0.5 * (2.0 * i / (planks - 1) - 1) for i in range(planks)]
    x, z = 0.0, top
    ends = [(x, z)]
    for t in tilt:
        x, z = x + length * math.cos(t), z + length * math.sin(t)
        ends.append((x, z))
    for i, t in enumerate(tilt):
        (x0, z0), (x1, z1) = ends[i], ends[i + 1]
        bodies.append({"id": "plank%02d" % i, "shape": "plank", "mass": 5.0,
                       "position": vec([(x0 + x1) / 2, 0, (z0 + z1) / 2]), "orientation": vec(axis_angle(0, 1, 0, -t))})
    hinge = {"axis_a": [0, 1, 0], "axis_b": [0, 1, 0], "ref_a": [1, 0, 0], "ref_b": [1, 0, 0]}
    forces.append(dict({"type": "hinge", "a": "plank00", "b": "world", "point_a": [-0.25, 0, 0],
                        "point_b": vec([ends[0][0], 0, ends[0][1]])}, **hinge))
    for i in range(planks - 1):
        f = {"type": "hinge", "a": "plank%02d" % i, "b": "plank%02d" % (i + 1), "point_a": [0.25, 0, 0],
             "point_b": [-0.25, 0, 0]}
        f.update(hinge)
        forces.append(f)
    forces.append(dict({"type": "hinge", "a": "plank%02d" % (planks - 1), "b": "world", "point_a": [0.25, 0, 0],
                        "point_b": vec([ends[-1][0], 0, ends[-1][1]])}, **hinge))
    for k in range(3):  # crates dropped onto the bridge
        bodies.append({"id": "crate%d" % k, "shape": "crate", "mass": 10.0 + 10.0 * k,
                       "position": vec([ends[-1][0] * (k + 1) / 4, 0.2 * (k - 1), top + 0.5 + 0.5 * k])})
    return {"description": "A 20 kg door swung on its hinge into its limits, and a bridge of twelve 5 kg planks hinged end "
                           "to end between two anchors with three crates (10-30 kg) dropped onto it.",
            "settings": {"dt": num(1 / 60), "sleeping": True},
            "shapes": shapes, "bodies": bodies, "forces": forces}


def cars():
    """Two cars on four sprung wheels: one driven by its wheels' motors into a row of crates, one
    dropped onto the ground beside it; wheel joints hold each wheel on its suspension."""
    shapes = [dict(GROUND), {"name": "chassis", "type": "box", "half_extents": [1.0, 0.6, 0.2]},
              {"name": "wheel", "type": "sphere", "radius": 0.35},
              {"name": "crate", "type": "box", "half_extents": [0.3, 0.3, 0.3]}]
    bodies, forces = [ground_body(0.9)], []
    rest, mass, stiffness = 0.3, 800.0, 4.0e4
    for car, (x, drop, speed) in enumerate([(-6.0, 0.0, 10.0), (0.0, 1.0, 0.0)]):
        y = 3.0 * car
        ride = 0.35 + rest + 0.3 + drop
        name = "car%d" % car
        bodies.append({"id": name, "shape": "chassis", "mass": mass, "position": vec([x, y, ride])})
        for k, (dx, dy) in enumerate([(-0.8, -0.9), (-0.8, 0.9), (0.8, -0.9), (0.8, 0.9)]):
            wheel = "%s_wheel%d" % (name, k)
            bodies.append({"id": wheel, "shape": "wheel", "mass": 15.0, "friction": 0.9,
                           "position": vec([x + dx, y + dy, ride - 0.3 - rest])})
            forces.append({"type": "wheel", "a": name, "b": wheel, "point_a": vec([dx, dy, -0.3]), "point_b": [0, 0, 0],
                           "suspension_a": [0, 0, -1], "axis_a": [0, 1, 0], "axis_b": [0, 1, 0],
                           "spring_stiffness": num(stiffness), "spring_damping": num(2 * math.sqrt(stiffness * mass / 4)),
                           "spring_travel": num(rest), "lower": -0.1, "upper": num(rest + 0.2),
                           "motor_speed": num(speed), "motor_torque": 400.0 if speed else 0.0})
    for k in range(4):  # the row of crates the driven car meets
        bodies.append({"id": "crate%d" % k, "shape": "crate", "mass": 20.0, "position": vec([4.0, -0.9 + 0.62 * k, 0.3])})
    return {"description": "Two 800 kg cars on four sprung 15 kg wheels: one driven at 10 rad/s by its wheels' motors "
                           "into a row of four 20 kg crates, one dropped 1 m onto its springs beside it.",
            "settings": {"dt": num(1 / 60), "sleeping": True},
            "shapes": shapes, "bodies": bodies, "forces": forces}


def terrain(rows=41, columns=41, spacing=0.5, seed=3):
    """Rolling hills as a height field and a ramp as a mesh, with balls, boxes and capsules
    dropped on the slopes to roll and slide into the hollows."""
    heights = []
    for i in range(rows):
        for j in range(columns):
            x, y = (j - (columns - 1) / 2) * spacing, (i - (rows - 1) / 2) * spacing
            heights.append(num(0.8 * math.sin(0.35 * x) * math.cos(0.3 * y) + 0.01 * (x * x + y * y)))
    # a 4 m wide ramp rising 2.4 m over 6 m (22 degrees), its low end a border the crates slide off
    ramp_v = [[-3, -2, 0], [3, -2, 2.4], [3, 2, 2.4], [-3, 2, 0]]
    shapes = [{"name": "hills", "type": "height_field", "rows": rows, "columns": columns,
               "spacing": [num(spacing), num(spacing)], "heights": heights},
              {"name": "ramp", "type": "mesh", "vertices": ramp_v, "triangles": [[0, 1, 2], [0, 2, 3]]},
              {"name": "ball", "type": "sphere", "radius": 0.3},
              {"name": "crate", "type": "box", "half_extents": [0.3, 0.25, 0.2]},
              {"name": "log", "type": "capsule", "radius": 0.15, "half_height": 0.4}]
    bodies = [{"id": "hills", "shape": "hills", "static": True, "friction": 0.6},
              {"id": "ramp", "shape": "ramp", "static": True, "friction": 0.2, "position": [4.0, 4.0, 1.2]}]
    r = Rng(seed)
    for k in range(24):
        kind = ("ball", "crate", "log")[k % 3]
        x, y = r.uniform(-8.0, 8.0), r.uniform(-8.0, 8.0)
        body = {"id": "%s%d" % (kind, k), "shape": kind, "mass": num(r.uniform(2.0, 20.0)),
                "position": vec([x, y, 3.0 + 0.5 * (k % 4)])}
        if kind != "ball":
            body["orientation"] = vec(random_small_rotation(r, 0.6))
        bodies.append(body)
    tilt = math.atan2(2.4, 6.0)
    for k in range(3):  # crates on the ramp's top, turned to lie on it, that slide down and off it
        x = 6.2
        bodies.append({"id": "ramp_crate%d" % k, "shape": "crate", "mass": 10.0,
                       "position": vec([x, 2.8 + 1.2 * k, 1.2 + (x - 1.0) * 0.4 + 0.2 / math.cos(tilt) + 0.01]),
                       "orientation": vec(axis_angle(0, 1, 0, -tilt))})
    return {"description": "Rolling hills (a 41 x 41 height field) and a mesh ramp, with 24 balls, crates and logs "
                           "dropped to roll and slide into the hollows, and 3 crates sliding down the ramp and off its end.",
            "settings": {"dt": num(1 / 60), "sleeping": True},
            "shapes": shapes, "bodies": bodies}


# ---- benchmark worlds: written on demand (--bench), not built-in scenes ----
#
# Box3D's benchmark scenes (its shared/benchmarks.c, CreateLargePyramid and CreateManyPyramids)
# turned from its y up to cellphys's z up: Box3D's x stays x, its y becomes z and its z becomes y.
# As there: cubes of half-extent 0.5 m at density 100 kg/m^3 (100 kg), friction 0.6 on every
# shape (Box3D's default material, the ground's too), each row resting exactly on the one
# below (no gap) and shifted by half a box, sleeping off. Gravity and the integrator are
# cellphys's defaults (Box3D's gravity is 10 m/s^2; its solver takes 4 substeps at 60 Hz).


def pyramid_boxes(base, h, x0, y, bodies, friction=0.6, density=100.0):
    """One layer of boxes in the x-z plane at y: `base` boxes on the ground, one fewer each row up,
    row i's centres at z = (2 i + 1) h and x = x0 + (i + 1) h + 2 (j - i) h (j = i .. base - 1)."""
    for i in range(base):
        z = (2.0 * i + 1.0) * h
        for j in range(i, base):
            x = x0 + (i + 1.0) * h + 2.0 * (j - i) * h
            bodies.append({"id": len(bodies), "shape": "box", "density": num(density),
                           "position": vec([x, y, z]), "friction": num(friction)})


def pyramid_scene(description, bodies, h):
    return {"description": description,
            "settings": {"dt": num(1 / 60), "integrator": "implicit_split", "solver": "cgs", "sleeping": False},
            "shapes": [GROUND, {"name": "box", "type": "box", "half_extents": [h, h, h]}],
            "bodies": bodies}


def large_pyramid(base=100, h=0.5):
    bodies = [ground_body(0.6)]
    pyramid_boxes(base, h, -h * base, 0.0, bodies)
    n = base * (base + 1) // 2
    return pyramid_scene(
        "Box3D's large pyramid: one layer of %s boxes (0.5 m half-extent cubes, 100 kg: density 100, friction 0.6) "
        "standing in the x-z plane on the ground, %d at the base centred on x = 0, each row up one fewer, shifted "
        "by half a box and resting exactly on the row below; sleeping off, 60 Hz." % ("{:,}".format(n), base),
        bodies, h)


def many_pyramids(base=10, rows=14, columns=14, h=0.5):
    bodies = [ground_body(0.6)]
    extent = h * columns * (base + 1.0)  # Box3D's ground half-width
    width = 2.0 * h * base
    y = -extent + 2.0 * h
    dy = 2.0 * (extent - 2.0 * h) / (rows - 1.0) if rows > 1 else 0.0
    for _ in range(rows):
        for j in range(columns):
            centre = -extent + j * (width + 2.0 * h) + 2.0 * h
            pyramid_boxes(base, h, centre - 0.5, y, bodies)
        y += dy
    each = base * (base + 1) // 2
    return pyramid_scene(
        "Box3D's many pyramids: a %d x %d grid of one-layer pyramids, %d boxes each (%d at the base), %s boxes in "
        "all (0.5 m half-extent cubes, 100 kg: density 100, friction 0.6); each pyramid stands in an x-z plane, "
        "its base from x = c - 0.5 to c + %g with c = %g + %g j, the rows of the grid at y = %g + %.6g i; sleeping "
        "off, 60 Hz." % (rows, columns, each, base, "{:,}".format(rows * columns * each), width - 0.5,
                         -extent + 2.0 * h, width + 2.0 * h, -extent + 2.0 * h, dy),
        bodies, h)


def sleep100k(n=100000):
    scene = sparse(n=n, area=100.0 * math.sqrt(n / 1000.0), seed=1)
    scene["description"] = ("world1000's mix at %s bodies and the same density (a %g m square): measured once it "
                            "has settled and every body sleeps." % ("{:,}".format(n), 100.0 * math.sqrt(n / 1000.0)))
    return scene


def ball_bin(n=400, half=3.0, seed=7):
    """n balls of mixed sizes (radius 0.12..0.4 m) and densities (200..2000 kg/m^3: up to 370
    to 1 in mass) dropped in layers into a bin 6 m square: one connected pile of loaded,
    rolling and sliding contacts once they land."""
    r = Rng(seed)
    shapes = [GROUND, {"name": "ball", "type": "sphere", "radius": 1},
              {"name": "wall_x", "type": "box", "half_extents": vec([half + 0.5, 0.25, 2.0])},
              {"name": "wall_y", "type": "box", "half_extents": vec([0.25, half, 2.0])}]
    bodies = [ground_body()]
    for s in (-1, 1):
        bodies.append({"id": "wall_x%+d" % s, "shape": "wall_x", "static": True, "position": vec([0, s * (half + 0.25), 2.0])})
        bodies.append({"id": "wall_y%+d" % s, "shape": "wall_y", "static": True, "position": vec([s * (half + 0.25), 0, 2.0])})
    m = int(2 * half / 0.9)
    for i in range(n):
        lay, col = i // (m * m), i % (m * m)
        x = -half + 0.45 + (col % m) * 0.9 + r.uniform(-0.05, 0.05)
        y = -half + 0.45 + (col // m) * 0.9 + r.uniform(-0.05, 0.05)
        bodies.append({"id": "ball%03d" % i, "shape": "ball", "scale": num(r.uniform(0.12, 0.4)),
                       "density": num(r.uniform(200, 2000)), "position": vec([x, y, 0.5 + lay * 0.9]),
                       "friction": 0.5})
    return {
        "description": "%d balls of mixed sizes (radius 0.12..0.4 m) and densities (200..2000 kg/m^3) dropped in "
                       "layers into a %g m square bin: a connected pile of loaded, rolling and sliding contacts." % (n, 2 * half),
        "settings": {"dt": num(1 / 60), "integrator": "implicit_split", "solver": "cgs"},
        "shapes": shapes,
        "bodies": bodies,
    }


BENCH_SCENES = {
    "ball_bin": ball_bin,
    "large_pyramid": large_pyramid,
    "many_pyramids": many_pyramids,
    "sleep100k": sleep100k,
}


SCENES = {
    "world1000": sparse,
    "pile65": pile,
    "stack10": stack10,
    "chain_ratio": chain_ratio,
    "spin": spin,
    "stiff_spring": stiff_spring,
    "incline": incline,
    "pendulum": pendulum,
    "newton_cradle": newton_cradle,
    "ragdoll_pile": ragdoll_pile,
    "door_and_bridge": door_and_bridge,
    "cars": cars,
    "terrain": terrain,
}


def compact(obj, indent=0):
    """JSON with one line per body/force/shape: readable and diff-friendly."""
    pad = "  " * indent
    if isinstance(obj, dict) and indent < 1:
        items = ['%s  "%s": %s' % (pad, k, compact(v, indent + 1)) for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(obj, list) and indent == 1 and obj and isinstance(obj[0], dict):
        return "[\n" + ",\n".join(pad + "  " + json.dumps(x) for x in obj) + "\n" + pad + "]"
    return json.dumps(obj)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None, help="default: examples/scenes (with --bench: build/bench-scenes)")
    ap.add_argument("--bench", action="store_true",
                    help="write the benchmark worlds (%s) instead of the built-in scenes" % ", ".join(BENCH_SCENES))
    args = ap.parse_args()
    here = os.path.dirname(os.path.abspath(__file__))
    out = args.out or (os.path.join(here, "..", "..", "build", "bench-scenes") if args.bench else here)
    os.makedirs(out, exist_ok=True)
    for name, make in (BENCH_SCENES if args.bench else SCENES).items():
        path = os.path.normpath(os.path.join(out, name + ".json"))
        with open(path, "w") as f:
            f.write(compact(make()) + "\n")
        print("wrote", path)


if __name__ == "__main__":
    main()

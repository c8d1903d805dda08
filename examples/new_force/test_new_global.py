#!/usr/bin/env python3
"""A force's new global, and a new joint, are each a descriptor and nothing else.

Copies examples/new_force to a temporary folder, adds a global to air_drag.yaml there (`gust`, a
uniform wind added to every instance's own) and writes a joint descriptor beside it (`universal`,
a Cardan joint: UNIVERSAL below), configures this project with CELLPHYS_FORCE_DIRS set to that
folder (tests, benchmarks and MPI off), builds only the `cellphys` command, and runs scenes that
use them:
- a ball at rest with no gravity is carried by the gust as quadratic drag must carry it,
  v(t) = w - w / (1 + k w t) with k = air_density drag / m, and stays at rest when the gust is
  left at its default;
- a drive shaft: an input shaft turned by a hinge's motor drives, through the universal joint, an
  output shaft hinged at an angle beta to it, whose speed follows the Cardan closed form
  w2 / w1 = cos(beta) / (1 - sin(beta)^2 sin(theta1)^2) (theta1 the input's angle from the pose in
  which its cross pin stands across the plane of the two shafts): between cos(beta) and
  1 / cos(beta) twice a turn.
The source tree is only read; the temporary tree is removed at the end, and everything is bounded
by --timeout.

    test_new_global.py --source DIR --cmake CMAKE --generator GEN --cxx CXX --simd PATH --build-type TYPE
"""
import argparse
import csv
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

GUST = [2.0, 0.0, 0.0]  # m/s
DENSITY, DRAG, MASS = 1.2, 0.5, 1.0  # kg/m^3, m^2, kg
DURATION = 2.0  # s
TOLERANCE = 5e-3  # relative, on the speed: the implicit step's error at dt = 1/240 s
CARDAN_TOLERANCE = 2e-2  # relative, on w2/w1: the soft joints' give at dt = 1/240 s


def add_gust(descriptor):
    """air_drag.yaml with the global `gust` added to the air velocity each instance declares."""
    d = yaml.safe_load(descriptor.read_text())
    assert "gust" not in d.get("globals", {}), "the example already has a gust"
    d.setdefault("globals", {})["gust"] = {"type": "vec3", "default": [0.0, 0.0, 0.0],
                                           "doc": "uniform wind added to every instance's own, world frame (m/s)"}
    assert d["let"]["vrel"] == "a.v - wind", d["let"]
    d["let"]["vrel"] = "a.v - wind - gust"
    descriptor.write_text(yaml.safe_dump(d, sort_keys=False))


# A Cardan joint as a force descriptor: the two bodies' points held together (as the hinge holds
# them) and an axis on each held at right angles, U = kr (na . nb)^2 / 2, its damper on the one
# relative turn that changes na . nb; the bodies turn freely about both axes.
UNIVERSAL = """\
name: universal
kind: binary
doc: "Universal (Cardan) joint: body points held together and an axis on each body held at right angles (a drive shaft's cross)."
world_anchor: true
joint: true
symmetric: false
params:
  point_a: {type: vec3, doc: "joint point on body a, body frame (m)"}
  point_b: {type: vec3, doc: "joint point on body b, body frame; world frame when b is the world (m)"}
  axis_a: {type: vec3, doc: "the cross's pin on body a, body frame (unit)"}
  axis_b: {type: vec3, doc: "the cross's pin on body b, body frame (unit), at right angles to axis_a"}
globals:
  joint_hertz: {type: f32, default: 60.0, greater_than: 0, setting: joint.hertz, doc: "joint stiffness as a frequency (Hz)"}
  joint_damping_ratio: {type: f32, default: 1.0, min: 0, setting: joint.damping_ratio, doc: "joint damping ratio"}
let:
  omega: 6.283185307179586 * joint_hertz
  zeta: joint_damping_ratio
  m: lagged(max(mass_of(a), mass_of(b)))
  im: lagged(max(moment_of(a), moment_of(b)))
  pa: world_point(a, point_a)
  pb: world_point(b, point_b)
  f: m * omega**2 * (pb - pa) + 2 * zeta * m * omega * (point_velocity(b, point_b) - point_velocity(a, point_a))
  na: world_axis(a, axis_a)
  nb: world_axis(b, axis_b)
  t: cross(na, nb)
  wrel: angular_velocity(b) - angular_velocity(a)
  tau: im * omega**2 * dot(na, nb) * t - 2 * zeta * im * omega * dot(wrel, t) * t
apply:
  - force_at_joint(a, pa, f)
  - force_at_joint(b, pb, -f)
  - torque(a, -tau)
  - torque(b, tau)
"""
BETA = math.radians(30)  # the angle between the shafts
TURN = 2 * math.pi       # the input's motor speed (rad/s)


def shaft_scene():
    """Two 1 m shafts hinged to the world, meeting at the origin in a universal joint."""
    d = [math.cos(BETA), 0.0, math.sin(BETA)]  # the output's axis; R_y(-beta) takes x onto it
    q = [math.cos(-BETA / 2), 0.0, math.sin(-BETA / 2), 0.0]
    hinge = {"type": "hinge", "b": "world", "point_a": [0, 0, 0], "axis_a": [1, 0, 0], "ref_a": [0, 1, 0],
             "ref_b": [0, 1, 0]}
    return {
        "description": "A drive shaft: a motor turns the input, a universal joint the output at 30 degrees.",
        "settings": {"dt": 1 / 240, "gravity": [0, 0, 0], "sleeping": False},
        "shapes": [{"name": "shaft", "type": "box", "half_extents": [0.5, 0.05, 0.05]}],
        "bodies": [{"id": "input", "shape": "shaft", "mass": 1, "position": [-0.5, 0, 0]},
                   {"id": "output", "shape": "shaft", "mass": 1, "position": [0.5 * x for x in d], "orientation": q}],
        "forces": [dict(hinge, a="input", point_b=[-0.5, 0, 0], axis_b=[1, 0, 0], motor_speed=TURN, motor_torque=50),
                   dict(hinge, a="output", point_b=[0.5 * x for x in d], axis_b=d),
                   {"type": "universal", "a": "input", "b": "output", "point_a": [0.5, 0, 0],
                    "point_b": [-0.5, 0, 0], "axis_a": [0, 1, 0], "axis_b": [0, 0, 1]}],
    }


def cardan(runner, exe, tmp):
    """The output's speed against the Cardan closed form over the last two of three seconds."""
    path, out = tmp / "shaft.json", tmp / "shaft.csv"
    path.write_text(json.dumps(shaft_scene(), indent=2))
    runner.run([exe, "run", path, "--duration", 3, "--out", out], stdout=subprocess.DEVNULL)
    d = (math.cos(BETA), 0.0, math.sin(BETA))
    rows = {}
    for r in csv.DictReader(out.open()):
        rows.setdefault(r["step"], {})[r["body"]] = r
    worst, lo, hi, n = 0.0, float("inf"), 0.0, 0
    for step, bodies in rows.items():
        a, b = bodies["input"], bodies["output"]
        if float(a["t"]) < 1.0:
            continue
        w1 = float(a["wx"])
        w2 = sum(float(b[k]) * c for k, c in zip(("wx", "wy", "wz"), d))
        theta1 = 2 * math.atan2(float(a["qx"]), float(a["qw"]))
        want = math.cos(BETA) / (1 - math.sin(BETA) ** 2 * math.sin(theta1) ** 2)
        worst = max(worst, abs(w2 / w1 - want) / want)
        lo, hi, n = min(lo, w2 / w1), max(hi, w2 / w1), n + 1
    print(f"drive shaft at {math.degrees(BETA):.0f} degrees, {n} steps: w2/w1 from {lo:.4f} to {hi:.4f} "
          f"(closed form {math.cos(BETA):.4f} to {1 / math.cos(BETA):.4f}); worst relative error {worst:.2e}")
    if n < 400 or worst > CARDAN_TOLERANCE:
        raise SystemExit(f"FAIL: the universal joint does not drive the output as a Cardan joint must (worst {worst:.2e})")


def scene(air_drag):
    """A scene with air_drag's globals under settings.air_drag (where the generator places a force's globals)."""
    return {
        "description": "A ball at rest, no gravity, in the air; a gust carries it along x.",
        "settings": {"dt": 1 / 240, "gravity": [0, 0, 0], "sleeping": False,
                     "air_drag": {"air_density": DENSITY, **air_drag}},
        "shapes": [{"name": "ball", "type": "sphere", "radius": 0.1}],
        "bodies": [{"id": "ball", "shape": "ball", "mass": MASS}],
        "forces": [{"type": "air_drag", "a": "ball", "drag": DRAG}],
    }


class Runner:
    """Runs commands in their own process group, all within one deadline (a timeout kills the group)."""

    def __init__(self, seconds):
        self.deadline = time.monotonic() + seconds

    def run(self, cmd, **kw):
        print("+", " ".join(map(str, cmd)), flush=True)
        p = subprocess.Popen(list(map(str, cmd)), start_new_session=True, **kw)
        try:
            rc = p.wait(timeout=max(1.0, self.deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
            raise SystemExit(f"FAIL: timed out: {' '.join(map(str, cmd))}")
        if rc != 0:
            raise SystemExit(f"FAIL: exit status {rc}: {' '.join(map(str, cmd))}")


def final_velocity(runner, exe, tmp, name, air_drag):
    path, out = tmp / f"{name}.json", tmp / f"{name}.csv"
    path.write_text(json.dumps(scene(air_drag), indent=2))
    runner.run([exe, "run", path, "--duration", DURATION, "--out", out, "--every", 60], stdout=subprocess.DEVNULL)
    rows = list(csv.DictReader(out.open()))
    last = rows[-1]
    return float(last["t"]), [float(last[k]) for k in ("vx", "vy", "vz")]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    for name in ("source", "cmake", "generator", "cxx", "simd", "build-type"):
        ap.add_argument("--" + name, required=True)
    ap.add_argument("--timeout", type=float, default=1200, help="seconds for the whole check")
    args = ap.parse_args()
    source = Path(args.source).resolve()
    runner = Runner(args.timeout)
    with tempfile.TemporaryDirectory(prefix="cellphys-new-global-") as t:
        tmp = Path(t)
        forces = tmp / "forces"
        shutil.copytree(source / "examples/new_force", forces)
        add_gust(forces / "air_drag.yaml")
        (forces / "universal.yaml").write_text(UNIVERSAL)
        build = tmp / "build"
        runner.run([args.cmake, "-S", source, "-B", build, "-G", args.generator, f"-DCMAKE_CXX_COMPILER={args.cxx}",
                    f"-DCMAKE_BUILD_TYPE={args.build_type}", f"-DCELLPHYS_SIMD={args.simd}",
                    f"-DCELLPHYS_FORCE_DIRS={forces}", "-DCELLPHYS_BUILD_TESTS=OFF", "-DCELLPHYS_BUILD_BENCH=OFF",
                    "-DCMAKE_DISABLE_FIND_PACKAGE_MPI=ON"], stdout=subprocess.DEVNULL)
        runner.run([args.cmake, "--build", build, "--target", "cellphys", "-j", os.cpu_count() or 2])
        exe = build / "tools/cellphys"

        t_end, still = final_velocity(runner, exe, tmp, "calm", {})
        if still != [0.0, 0.0, 0.0]:
            raise SystemExit(f"FAIL: with the gust at its default the ball moved: v = {still}")
        t_end, v = final_velocity(runner, exe, tmp, "gust", {"gust": GUST})
        w, k = GUST[0], DENSITY * DRAG / MASS
        want = w - w / (1 + k * w * t_end)
        err = abs(v[0] - want) / want
        print(f"gust {w} m/s, t = {t_end:.3f} s: vx = {v[0]:.6f} m/s, closed form {want:.6f} (relative error {err:.2e})")
        if err > TOLERANCE or v[1] != 0.0 or v[2] != 0.0:
            raise SystemExit(f"FAIL: the gust did not carry the ball as drag must: v = {v}, want [{want}, 0, 0]")
        cardan(runner, exe, tmp)
    print("ok: a global added to a descriptor and a joint added as one are used from scene files as they must be")
    return 0


if __name__ == "__main__":
    sys.exit(main())

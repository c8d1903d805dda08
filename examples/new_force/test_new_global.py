#!/usr/bin/env python3
"""A force's new global is one descriptor edit and nothing else.

Copies examples/new_force to a temporary folder, adds a global to air_drag.yaml there (`gust`, a
uniform wind added to every instance's own), configures this project with CELLPHYS_FORCE_DIRS set
to that folder (tests, benchmarks and MPI off), builds only the `cellphys` command, and runs a
scene whose settings set the new global. A ball at rest with no gravity is carried by the gust as
quadratic drag must carry it, v(t) = w - w / (1 + k w t) with k = air_density drag / m, and stays
at rest when the gust is left at its default. The source tree is only read; the temporary tree is
removed at the end, and everything is bounded by --timeout.

    test_new_global.py --source DIR --cmake CMAKE --generator GEN --cxx CXX --simd PATH --build-type TYPE
"""
import argparse
import csv
import json
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


def add_gust(descriptor):
    """air_drag.yaml with the global `gust` added to the air velocity each instance declares."""
    d = yaml.safe_load(descriptor.read_text())
    assert "gust" not in d.get("globals", {}), "the example already has a gust"
    d.setdefault("globals", {})["gust"] = {"type": "vec3", "default": [0.0, 0.0, 0.0],
                                           "doc": "uniform wind added to every instance's own, world frame (m/s)"}
    assert d["let"]["vrel"] == "a.v - wind", d["let"]
    d["let"]["vrel"] = "a.v - wind - gust"
    descriptor.write_text(yaml.safe_dump(d, sort_keys=False))


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
    print("ok: a global added to a descriptor is set from a scene file and moves the body as it must")
    return 0


if __name__ == "__main__":
    sys.exit(main())

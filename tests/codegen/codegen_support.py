"""Shared helpers for the code generator tests (not a test module: discovery only loads test*.py).

The tests locate the repository from this file, import cellphys_codegen from <root>/codegen and
run <root>/codegen/generate.py with the interpreter that runs the tests. Every descriptor a test
writes goes into a temporary directory that is removed when the test ends.
"""
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CODEGEN = ROOT / "codegen"
GENERATE = CODEGEN / "generate.py"
REAL_STRUCTS = CODEGEN / "descriptors" / "structs"
REAL_FORCES = CODEGEN / "descriptors" / "forces"
EXAMPLE_FORCES = ROOT / "examples" / "new_force"

if str(CODEGEN) not in sys.path:
    sys.path.insert(0, str(CODEGEN))

from cellphys_codegen.cxx_printer import UnsupportedExpression  # noqa: E402,F401
from cellphys_codegen.emit import render  # noqa: E402
from cellphys_codegen.errors import DescriptorError  # noqa: E402

# A small, self-contained descriptor set: one struct, one global force (so Island_Params has a
# field) and one unary force with per-instance params. Independent of the real descriptors.
PROBE_STRUCT = """\
    name: Probe
    doc: "A small struct of every kind of field."
    align: 16
    fields:
      - {name: position, type: vec3, doc: "m"}
      - {name: mass, type: f32}
      - {name: ids, type: i32, count: 3}
"""

PULL_FORCE = """\
    name: pull
    kind: global
    doc: "A uniform acceleration (the probe set's only global)."
    symmetric: true
    globals:
      pull_accel: {type: vec3, default: [0.0, 0.0, -1.0], doc: "m/s^2"}
    apply:
      - force(a, a.mass * pull_accel)
"""

TETHER_FORCE = """\
    name: tether
    kind: unary
    doc: "A linear spring from the centre of mass to a fixed anchor."
    params:
      stiffness: {type: f32, min: 0, doc: "N/m"}
      anchor: {type: vec3, doc: "world frame (m)"}
    apply:
      - force(a, stiffness * (anchor - a.x))
"""


def write(directory, name, text):
    """Write a descriptor (dedented) and return its path exactly as the generator will name it."""
    path = Path(directory) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(textwrap.dedent(text))
    return path


def temp_dir(testcase):
    """A temporary directory removed when the test (or class, for setUpClass) is cleaned up."""
    d = tempfile.TemporaryDirectory(prefix="cellphys-codegen-test-")
    if isinstance(testcase, type):
        testcase.addClassCleanup(d.cleanup)
    else:
        testcase.addCleanup(d.cleanup)
    return Path(d.name)


class Sandbox:
    """A structs dir and a forces dir in a temporary directory."""

    def __init__(self, root, probe=True, real_structs=(), all_real_structs=False):
        self.root = Path(root)
        self.structs = self.root / "structs"
        self.forces = self.root / "forces"
        self.structs.mkdir(parents=True)
        self.forces.mkdir(parents=True)
        if all_real_structs:
            for p in sorted(REAL_STRUCTS.glob("*.yaml")):
                shutil.copy(p, self.structs / p.name)
        for name in real_structs:
            shutil.copy(REAL_STRUCTS / name, self.structs / name)
        if probe:
            write(self.structs, "probe.yaml", PROBE_STRUCT)
            write(self.forces, "pull.yaml", PULL_FORCE)

    def copy_to(self, root):
        """An independent copy of this sandbox's descriptors under root (a new directory)."""
        shutil.copytree(self.root, root)
        other = Sandbox.__new__(Sandbox)
        other.root = Path(root)
        other.structs = other.root / "structs"
        other.forces = other.root / "forces"
        return other

    def struct(self, name, text):
        return write(self.structs, name, text)

    def force(self, name, text):
        return write(self.forces, name, text)

    def render(self, extra_force_dirs=()):
        return render(str(self.structs), [str(self.forces)] + [str(d) for d in extra_force_dirs], ROOT)

    def cli_args(self):
        return ["--structs", str(self.structs), "--forces", str(self.forces)]


def run_generator(*args, env_extra=None, timeout=180):
    """Run generate.py as the build does; returns the CompletedProcess (text mode)."""
    env = dict(os.environ)
    if env_extra:
        env.update(env_extra)
    return subprocess.run([sys.executable, str(GENERATE), *map(str, args)], capture_output=True, text=True,
                          env=env, timeout=timeout, cwd=str(ROOT))


def snapshot(directory):
    """{relative path: bytes} of every file under directory (hidden ones included)."""
    directory = Path(directory)
    return {str(p.relative_to(directory)): p.read_bytes() for p in sorted(directory.rglob("*")) if p.is_file()}


class DescriptorErrorAssertions:
    """Mixin for unittest.TestCase."""

    def assertDescriptorError(self, fn, path, field, reason_pattern):
        """fn() must raise DescriptorError for `path` at `field` with a reason matching the regex."""
        with self.assertRaises(DescriptorError) as cm:
            fn()
        e = cm.exception
        self.assertEqual(e.path, str(path), f"wrong file in {e}")
        self.assertEqual(e.field, field, f"wrong field in {e}")
        self.assertRegex(str(e.reason), reason_pattern)
        self.assertTrue(str(e).startswith(f"{path}: {field}: "), str(e))
        self.assertNotEqual(str(e.reason).strip(), "")
        return e

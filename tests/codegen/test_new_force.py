"""Adding a force is only a descriptor; generation is deterministic; kernels carry their annotations.

One generation of the real descriptor set (codegen/descriptors and examples/new_force) plus one new
descriptor, run twice in parallel with different hash seeds: the trees must be byte-identical.
"""
import json
import os
import re
import shutil
import subprocess
import sys
import unittest

from codegen_support import (EXAMPLE_FORCES, GENERATE, REAL_FORCES, ROOT, Sandbox, snapshot, temp_dir, write)

NEW_FORCE = """\
    name: anchor_spring
    kind: unary
    doc: "A linear spring pulling the centre of mass to the world origin."
    params:
      stiffness: {type: f32, min: 0, doc: "N/m"}
    apply:
      - force(a, -stiffness * a.x)
"""


class NewForceTests(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        sb = Sandbox(temp_dir(cls), probe=False, all_real_structs=True)
        for p in sorted(REAL_FORCES.glob("*.yaml")):
            shutil.copy(p, sb.forces / p.name)
        write(sb.forces, "anchor_spring.yaml", NEW_FORCE)
        cls.real_names = sorted(p.stem for p in REAL_FORCES.glob("*.yaml")) + \
            sorted(p.stem for p in EXAMPLE_FORCES.glob("*.yaml"))
        out = temp_dir(cls)
        cls.outs = [out / "one", out / "two"]
        procs = []
        for seed, o in zip(("0", "4242"), cls.outs):
            env = dict(os.environ, PYTHONHASHSEED=seed)
            procs.append(subprocess.Popen(
                [sys.executable, str(GENERATE), "--out", str(o), "--quiet", *sb.cli_args(),
                 "--forces", str(EXAMPLE_FORCES)],
                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=str(ROOT)))
        for p in procs:
            _, err = p.communicate(timeout=300)
            if p.returncode != 0:
                raise AssertionError(f"generation with the new force failed ({p.returncode}): {err}")
        cls.files = {k: v.decode() for k, v in snapshot(cls.outs[0]).items()}
        cls.gen = "cellphys/gen/"

    def text(self, name):
        return self.files[self.gen + name]

    # ---- 5. a new force is only a descriptor ----
    def test_kernel_header_exists(self):
        self.assertTrue((self.outs[0] / "cellphys/gen/forces/anchor_spring.h").is_file())
        kernel = self.text("forces/anchor_spring.h")
        self.assertIn("struct Anchor_Spring_Body_Kernel {", kernel)
        self.assertIn("using Instance = Anchor_Spring_Force;", kernel)
        self.assertIn("static constexpr ForceType kType = ForceType::anchor_spring;", kernel)
        self.assertRegex(kernel, r"in\[\d+ \* stride\] = f\.stiffness;")
        self.assertRegex(kernel, r"in\[\d+ \* stride\] = a\.position\[0\];")

    def test_force_type_enum(self):
        self.assertRegex(self.text("kernel_types.h"), r"(?m)^  anchor_spring = \d+,$")
        n = len(self.real_names) + 1
        self.assertIn(f"inline constexpr int kNumForceTypes = {n};", self.text("kernel_types.h"))

    def test_force_table_entry(self):
        table = self.text("force_table.h")
        self.assertIn('#include "cellphys/gen/forces/anchor_spring.h"', table)
        self.assertRegex(table, r'(?m)^    \{"anchor_spring", ForceType::anchor_spring, ForceKind::unary, false, false, false, '
                                r'"Anchor_Spring_Force", sizeof\(Anchor_Spring_Force\), alignof\(Anchor_Spring_Force\), '
                                r'offsetof\(Anchor_Spring_Force, body_a\), -1, kAnchor_SpringParams, 1, ')
        self.assertRegex(table, r'inline constexpr ParamInfo kAnchor_SpringParams\[\] = \{\n'
                                r'    \{"stiffness", ParamType::f32, 0, 1, true, 0\.0f, "N/m"\},\n\};')
        visit = table[table.index("inline void visit_kernels("):]
        self.assertIn("  v(Anchor_Spring_Body_Kernel{});", visit)

    def test_instance_struct_in_layouts(self):
        layouts = self.text("layouts.h")
        self.assertRegex(layouts, r"struct alignas\(4\) Anchor_Spring_Force \{\n"
                                  r"  float stiffness;  ///< @0: f32\. N/m\n"
                                  r"  int32_t body_a;  ///< @4: i32\n\};")
        self.assertIn('static_assert(sizeof(Anchor_Spring_Force) == 8, "Anchor_Spring_Force: size differs', layouts)
        info = json.loads(self.text("layouts.json"))["Anchor_Spring_Force"]
        self.assertEqual(info, {"align": 4, "size": 8, "payload": 8, "offsets": {"stiffness": 0, "body_a": 4}})

    def test_real_forces_are_all_still_generated(self):
        table = self.text("force_table.h")
        entries = re.findall(r'(?m)^    \{"(\w+)", ForceType::\1, ', table)
        self.assertEqual(sorted(entries), sorted(self.real_names + ["anchor_spring"]))
        for name in self.real_names:
            self.assertIn(f"forces/{name}.h", "\n".join(self.files))
        self.assertEqual(sorted(n for n in self.files if n.startswith(self.gen + "forces/")),
                         sorted(f"{self.gen}forces/{n}.h" for n in self.real_names + ["anchor_spring"]))

    # ---- 7. kernel annotations ----
    def test_kernel_annotations(self):
        kernel = self.text("forces/anchor_spring.h")
        m = re.search(r"/// Total ops: (\d+)\n", kernel)
        self.assertIsNotNone(m, "no '/// Total ops: N' annotation")
        self.assertIn(f"static constexpr int kOps = {m.group(1)};", kernel)
        self.assertIn("template <class S>", kernel)
        self.assertIn("static inline void eval([[maybe_unused]] const S* in, [[maybe_unused]] S h, S* out)", kernel)
        # F = -k x: one dF/ddelta block for body a, nothing else
        self.assertIn("static constexpr int kNumBlocks = 1;", kernel)
        self.assertIn("{BlockKind::dF_ddelta, 0, 0},", kernel)

    # ---- 6. determinism ----
    def test_two_generations_are_byte_identical(self):
        one, two = snapshot(self.outs[0]), snapshot(self.outs[1])
        self.assertEqual(sorted(one), sorted(two))
        for name in one:
            self.assertEqual(one[name], two[name], f"{name} differs between two generations")


if __name__ == "__main__":
    unittest.main()

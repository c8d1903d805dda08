"""Force kernels as statements: one macro prints every kind, and every block of a kernel names the
let or apply entry of its descriptor, with the file and line, so a wrong kernel leads to its YAML.
"""
import re
import shutil
import unittest
from pathlib import Path

import jinja2

from codegen_support import (EXAMPLE_FORCES, REAL_FORCES, ROOT, Sandbox, render, temp_dir, write)
from cellphys_codegen import yaml_loader
from cellphys_codegen.forces import load_force
from cellphys_codegen.kernel_code import kernel_view
from cellphys_codegen.statements import Statement
from cellphys_codegen.structs import load_structs

# Line numbers matter here: the tests below name them.
PROBE = """\
name: probe_force
kind: unary
params:
  stiffness: {type: f32, min: 0}
  anchor: {type: vec3}
let:
  # a comment and a blank line do not shift the lines

  tip: world_point(a, vec(0, 0, 1))
  d: anchor - tip
  s: lagged(1 + dot(d, d))
apply:
  - force_at_point(a, tip, stiffness * d / s)
  - torque(a, -stiffness * inertia_world(a) * a.w)
"""

# let X, apply[i] or apply, then (file:line)
ORIGIN = re.compile(r"(let (?P<let>\w+)|apply\[(?P<item>\d+)\]|(?P<apply>apply)) \((?P<file>[\w.]+):(?P<line>\d+)\)")


def bodies(kernel):
    """{entry point: its body} of the first kernel struct in a generated header."""
    out = {}
    for name in ("gather", "eval", "eval_implicit", "eval_f"):
        start = kernel.index(f"static inline void {name}(")
        start = kernel.index("{\n", start) + 2
        out[name] = kernel[start:kernel.index("\n  }\n", start)]
    return out


def comments(body):
    return [line.strip()[3:] for line in body.splitlines() if line.strip().startswith("// ")]


class OriginCommentTests(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        sb = Sandbox(temp_dir(cls))
        write(sb.forces, "probe_force.yaml", PROBE)
        cls.kernel = sb.render()["cellphys/gen/forces/probe_force.h"]
        cls.body = bodies(cls.kernel)

    def test_each_let_and_apply_entry_is_named_with_its_line(self):
        pre = "body-frame quantities rotated to world, first used by let tip (probe_force.yaml:9), " \
              "apply[1] (probe_force.yaml:14)"
        lets = ["let tip (probe_force.yaml:9)", "let d (probe_force.yaml:10)", "let s (probe_force.yaml:11)"]
        both = "apply[0] (probe_force.yaml:13), apply[1] (probe_force.yaml:14)"
        shared = "apply (probe_force.yaml:12), shared subexpressions"
        self.assertEqual(comments(self.body["eval"]), [pre] + lets + [
            shared, f"F_a from {both}", f"dF_a/ddelta_a from {both}", f"dF_a/du_a from {both}"])
        self.assertEqual(comments(self.body["eval_implicit"]), [pre] + lets + [
            shared, f"g_a from {both}", f"K_aa from {both}"])
        self.assertEqual(comments(self.body["eval_f"]), [pre] + lets + [shared, f"F_a from {both}"])
        self.assertEqual(comments(self.body["gather"]), [])

    def test_a_comment_heads_the_code_of_its_let(self):
        f = self.body["eval_f"]
        held = f[f.index("// let s "):f.index("// apply ")]
        self.assertIn("const S L_s = held_in ? held_in[0] : S(", held)
        self.assertIn("if (held_out) held_out[0] = L_s;", held)
        e = self.body["eval"]
        tip = e[e.index("// let tip "):e.index("// let d ")]
        self.assertIn("const S L_tip__0 = ", tip)
        self.assertIn("const S d_L_tip__0__a_dtz = ", tip)
        self.assertIn("[[maybe_unused]] const S L_s = ", e[e.index("// let s "):e.index("// apply ")])
        self.assertIn("out[0] = ", e[e.index("// F_a "):e.index("// dF_a/ddelta_a ")])


class RealDescriptorOriginTests(unittest.TestCase):
    """Every origin comment in every real kernel names the right line of the right file."""

    @classmethod
    def setUpClass(cls):
        sb = Sandbox(temp_dir(cls), probe=False, all_real_structs=True)
        for p in sorted(REAL_FORCES.glob("*.yaml")):
            shutil.copy(p, sb.forces / p.name)
        cls.files = render(str(sb.structs), [str(sb.forces), str(EXAMPLE_FORCES)], ROOT)
        cls.sources = {p.name: p for p in list(REAL_FORCES.glob("*.yaml")) + list(EXAMPLE_FORCES.glob("*.yaml"))}

    def test_origin_lines(self):
        headers = {k: v for k, v in self.files.items() if k.startswith("cellphys/gen/forces/")}
        self.assertEqual(len(headers), len(self.sources))
        for name, kernel in headers.items():
            source = self.sources[Path(name).stem + ".yaml"]
            yaml_lines = source.read_text().splitlines()
            apply_line = next(i for i, t in enumerate(yaml_lines, 1) if t.startswith("apply:"))
            items = [i for i, t in enumerate(yaml_lines, 1) if i > apply_line and t.lstrip().startswith("- ")]
            lets, applies = set(), set()
            for m in ORIGIN.finditer(kernel):
                with self.subTest(kernel=name, origin=m.group(0)):
                    self.assertEqual(m.group("file"), source.name)
                    line = int(m.group("line"))
                    if m.group("let"):
                        self.assertRegex(yaml_lines[line - 1], rf"^\s+{m.group('let')}:")
                        lets.add(m.group("let"))
                    elif m.group("item"):
                        self.assertEqual(line, items[int(m.group("item"))])
                        applies.add(int(m.group("item")))
                    else:
                        self.assertEqual(line, apply_line)
            # every let heads a block; every apply entry is named by an output (a world-side one in the pair kernel)
            data, _ = yaml_loader.load_with_lines(source)
            self.assertEqual(lets, set(data.get("let") or {}), name)
            self.assertEqual(applies, set(range(len(data["apply"]))), name)


class StatementMacroTests(unittest.TestCase):
    """templates/util/util.jinja prints every kind of statement; the force template prints none itself."""

    def print(self, code, pad="  "):
        env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(ROOT / "templates")),
                                 undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True,
                                 keep_trailing_newline=True)
        t = env.from_string('{% import "util/util.jinja" as u %}\n{{ u.statements(code, pad) }}\nend\n')
        return t.render(code=code, pad=pad)

    def test_every_kind(self):
        let = "let x (probe.yaml:3)"
        code = [
            Statement("input", "S", "a_px", "in[0]", maybe_unused=True),
            Statement("temporary", "S", "p0_0", "(a_px*a_px)", "preamble"),
            Statement("value", "S", "a_r0_0", "p0_0", "preamble"),
            Statement("temporary", "auto", "l0_0_0", "(a_px > S(0))", let),
            Statement("value", "S", "L_x", "select(l0_0_0, a_px, S(0))", let, held=True, maybe_unused=True),
            Statement("value", "S", "L_y", "sqrt(L_x)", "let y (probe.yaml:4)", held=True, slot=2),
            Statement("output", "", "out[0]", "L_y", "F_a from apply[0] (probe.yaml:6)"),
            Statement("output", "", "out[1]", "S(0)", "F_a from apply[0] (probe.yaml:6)"),
        ]
        self.assertEqual(self.print(code), """\
  [[maybe_unused]] const S a_px = in[0];
  // preamble
  const S p0_0 = (a_px*a_px);
  const S a_r0_0 = p0_0;
  // let x (probe.yaml:3)
  const auto l0_0_0 = (a_px > S(0));
  [[maybe_unused]] const S L_x = select(l0_0_0, a_px, S(0));
  // let y (probe.yaml:4)
  const S L_y = held_in ? held_in[2] : S(sqrt(L_x));
  if (held_out) held_out[2] = L_y;
  // F_a from apply[0] (probe.yaml:6)
  out[0] = L_y;
  out[1] = S(0);
end
""")

    def test_force_template_prints_no_statement_itself(self):
        template = (ROOT / "templates" / "force_kernel.h.j2").read_text()
        self.assertEqual(template.count("u.statements("), 4)  # gather, eval, eval_implicit, eval_f
        for text in ("const S {{", "out[", "in[{{", "held_in[", "{{ line }}"):
            self.assertNotIn(text, template)


class StatementDataTests(unittest.TestCase):
    """The kernel's view is data: kinds, names, held slots and origins, not lines of C++."""

    def test_kernel_view(self):
        d = temp_dir(self)
        sb = Sandbox(d)
        path = write(sb.forces, "probe_force.yaml", PROBE)
        k = load_force(path, {s.name: s for s in load_structs(sb.structs)}).kernels[0]
        view = kernel_view(k.force, k)
        for entry in ("code", "i_code", "f_code", "gather"):
            self.assertTrue(all(isinstance(s, Statement) for s in view[entry]), entry)
        self.assertEqual({s.kind for s in view["code"]}, {"input", "temporary", "value", "output"})
        self.assertTrue(all(s.origin is None for s in view["code"] if s.kind == "input"))
        self.assertTrue(all(s.origin for s in view["code"] if s.kind != "input"))
        held = [s for s in view["f_code"] if s.held]
        self.assertEqual([(s.name, s.slot, s.origin) for s in held], [("L_s", 0, "let s (probe_force.yaml:11)")])
        self.assertEqual(view["num_held"], 1)
        self.assertEqual([(s.name, s.slot, s.maybe_unused) for s in view["code"] if s.held], [("L_s", None, True)])
        self.assertEqual([s.name for s in view["code"] if s.kind == "output"],
                         [f"out[{i}]" for i in range(view["num_outputs"])])


class YamlLineTests(unittest.TestCase):
    def test_lines_of_keys_and_items(self):
        path = write(temp_dir(self), "probe.yaml", """\
            # comment
            name: probe
            let:

              x: 1
              y: {z: 2}
            apply:
              - first
              -   second
            flow: [a, b]
            """)
        data, lines = yaml_loader.load_with_lines(path)
        self.assertEqual(data["let"], {"x": 1, "y": {"z": 2}})
        self.assertEqual(lines, {"name": 2, "let": 3, "let.x": 5, "let.y": 6, "let.y.z": 6, "apply": 7,
                                 "apply[0]": 8, "apply[1]": 9, "flow": 10, "flow[0]": 10, "flow[1]": 10})
        self.assertEqual(yaml_loader.load(path), data)


if __name__ == "__main__":
    unittest.main()

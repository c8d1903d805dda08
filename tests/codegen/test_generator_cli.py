"""generate.py as the build runs it: exit codes, error format, untouched trees on errors, --check."""
import re
import shutil
import unittest

from codegen_support import (EXAMPLE_FORCES, REAL_FORCES, ROOT, TETHER_FORCE, Sandbox, run_generator, snapshot, temp_dir,
                             write)

ERROR_LINE = re.compile(r"^cellphys codegen: error: (?P<file>[^:\n]+): (?P<field>[^:\n]+): (?P<reason>.+)$", re.M)


def make_probe_set(testcase):
    sb = Sandbox(temp_dir(testcase))
    sb.force("tether.yaml", TETHER_FORCE)
    return sb


class CliErrorTests(unittest.TestCase):
    """A malformed descriptor: exit 2, one clean error line, the previous tree byte-for-byte intact."""

    @classmethod
    def setUpClass(cls):
        cls.sb = make_probe_set(cls)
        cls.good_out = temp_dir(cls) / "generated"
        r = run_generator("--out", cls.good_out, *cls.sb.cli_args())
        if r.returncode != 0:
            raise AssertionError(f"good probe set does not generate: {r.stderr}")
        cls.good = snapshot(cls.good_out)

    def setUp(self):
        # a private copy of the descriptors and of the previously generated tree
        self.sb = self.__class__.sb.copy_to(temp_dir(self) / "descriptors")
        self.out = temp_dir(self) / "generated"
        shutil.copytree(self.good_out, self.out)
        self.assertEqual(snapshot(self.out), self.good)

    def run_broken(self, expected_file=None, expected_field=None, reason_pattern=None):
        r = run_generator("--out", self.out, *self.sb.cli_args())
        self.assertEqual(r.returncode, 2, f"stdout={r.stdout!r} stderr={r.stderr!r}")
        self.assertNotIn("Traceback", r.stderr)
        self.assertEqual(r.stdout, "")
        self.assertTrue(r.stderr.startswith("cellphys codegen: error: "), r.stderr)
        if expected_file is not None:
            m = ERROR_LINE.search(r.stderr)
            self.assertIsNotNone(m, f"no 'file: field: reason' line in {r.stderr!r}")
            self.assertEqual(m.group("file"), str(expected_file))
            if isinstance(expected_field, re.Pattern):
                self.assertRegex(m.group("field"), expected_field)
            else:
                self.assertEqual(m.group("field"), expected_field)
            self.assertRegex(m.group("reason"), reason_pattern)
        after = snapshot(self.out)
        self.assertEqual(sorted(after), sorted(self.good), "file set changed")
        for name in self.good:
            self.assertEqual(after[name], self.good[name], f"{name} changed")
        return r

    def test_good_set_generates_expected_files(self):
        self.assertEqual(sorted(self.good), [
            "cellphys/gen/.stamp", "cellphys/gen/block_ops.h", "cellphys/gen/force_table.h",
            "cellphys/gen/forces/pull.h", "cellphys/gen/forces/tether.h", "cellphys/gen/kernel_types.h",
            "cellphys/gen/layouts.h", "cellphys/gen/layouts.json"])

    def test_struct_with_unknown_field_type(self):
        p = self.sb.struct("probe.yaml", "name: Probe\nfields:\n  - {name: a, type: f32}\n  - {name: b, type: vec5}\n")
        self.run_broken(p, "fields[1].type", r"unknown type 'vec5'")

    def test_struct_with_bad_align(self):
        p = self.sb.struct("probe.yaml", "name: Probe\nalign: 12\nfields:\n  - {name: a, type: f32}\n")
        self.run_broken(p, "align", r"must be 4, 8, 16, 32 or 64, got 12")

    def test_two_structs_with_the_same_name(self):
        p = self.sb.struct("zz_probe_again.yaml", "name: Probe\nfields:\n  - {name: a, type: f32}\n")
        self.run_broken(p, "name", r"struct 'Probe' is also declared in .*probe\.yaml")

    def test_force_with_unknown_name(self):
        p = self.sb.force("tether.yaml", TETHER_FORCE.replace("stiffness * (anchor", "stifness * (anchor"))
        self.run_broken(p, "apply[0]", r"unknown name 'stifness'")

    def test_force_expression_that_does_not_parse(self):
        p = self.sb.force("tether.yaml", TETHER_FORCE.replace("(anchor - a.x))", "(anchor - a.x)"))
        self.run_broken(p, "apply[0]", r"does not parse")

    def test_force_with_invalid_yaml(self):
        p = self.sb.force("tether.yaml", TETHER_FORCE.replace("apply:", "apply: [\n"))
        self.run_broken(p, "(file)", r"not valid YAML")

    def test_force_calling_a_non_primitive(self):
        p = self.sb.force("tether.yaml", TETHER_FORCE.replace("stiffness * (anchor - a.x)", "__import__('os').getcwd()"))
        self.run_broken(p, "apply[0]", r"only the primitives")

    def test_unsupported_power_exits_2_cleanly(self):
        # differentiable, but cxx_printer has no vectorisable form: UnsupportedExpression -> exit 2
        self.sb.force("tether.yaml", TETHER_FORCE.replace("stiffness * (anchor", "stiffness**1.7 * (anchor"))
        r = self.run_broken()
        self.assertIn("power", r.stderr)
        self.assertIn("1.7", r.stderr)

    def test_error_does_not_create_the_output_directory(self):
        self.sb.force("tether.yaml", TETHER_FORCE.replace("kind: unary", "kind: ternary"))
        fresh = temp_dir(self) / "not-yet"
        r = run_generator("--out", fresh, *self.sb.cli_args())
        self.assertEqual(r.returncode, 2)
        self.assertFalse(fresh.exists())

    def test_regenerating_an_up_to_date_tree_rewrites_nothing(self):
        # the class's own descriptors: the headers name their descriptor's path ("// Source: ...")
        before = {p: p.stat().st_mtime_ns for p in self.out.rglob("*") if p.is_file() and p.name != ".stamp"}
        r = run_generator("--out", self.out, *self.__class__.sb.cli_args())
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(snapshot(self.out), self.good)
        after = {p: p.stat().st_mtime_ns for p in self.out.rglob("*") if p.is_file() and p.name != ".stamp"}
        self.assertEqual(before, after)

    # regression: UnsupportedExpression (cxx_printer) carries no descriptor file or field, and
    # generate.py prints it as is: "cellphys codegen: error: power p_stiffness**1.7... has no
    # vectorisable form" -- the user cannot tell which descriptor (or which apply/let entry) to fix.
    def test_unsupported_power_error_names_the_file(self):
        p = self.sb.force("tether.yaml", TETHER_FORCE.replace("stiffness * (anchor", "stiffness**1.7 * (anchor"))
        self.run_broken(p, re.compile(r"^apply(\[0\])?$"), r"power")

    # regression: a comparison inside a vector (`vec(a.mass > 1, 0, 0)`) raises TypeError in
    # forces._build_kernel outside evaluate()'s try: generate.py dies with a Python traceback and
    # exit status 1 (which the build reads as "drift") instead of exit 2 and a file: field: reason line.
    def test_comparison_inside_a_vector_exits_2_cleanly(self):
        p = self.sb.force("tether.yaml", TETHER_FORCE.replace("stiffness * (anchor - a.x)", "vec(a.mass > 1, 0, 0)"))
        self.run_broken(p, "apply[0]", r".")


class CheckTests(unittest.TestCase):
    """--check DIR: 0 when DIR equals a fresh generation, 1 with a diff and the refresh command."""

    @classmethod
    def setUpClass(cls):
        cls.sb = make_probe_set(cls)
        cls.ref = temp_dir(cls) / "generated"
        r = run_generator("--out", cls.ref, *cls.sb.cli_args())
        if r.returncode != 0:
            raise AssertionError(f"good probe set does not generate: {r.stderr}")

    def setUp(self):
        self.tree = temp_dir(self) / "checked-in"
        shutil.copytree(self.ref, self.tree)
        self.gen = self.tree / "cellphys" / "gen"

    def check(self, expected_rc, *extra):
        before = snapshot(self.tree) if self.tree.exists() else None
        r = run_generator("--check", self.tree, *self.sb.cli_args(), *extra)
        self.assertEqual(r.returncode, expected_rc, f"stdout={r.stdout!r} stderr={r.stderr!r}")
        self.assertNotIn("Traceback", r.stderr)
        if before is not None:
            self.assertEqual(snapshot(self.tree), before, "--check modified the tree")
        return r

    def assertDrift(self, r, relpath):
        self.assertIn(f"--- checked-in/{relpath}", r.stdout)
        self.assertIn(f"+++ fresh/{relpath}", r.stdout)
        self.assertRegex(r.stdout, r"(?m)^@@ ")
        self.assertIn("scripts/regenerate", r.stderr)
        self.assertIn(str(self.tree), r.stderr)

    def test_fresh_tree(self):
        r = self.check(0)
        self.assertIn("is up to date", r.stdout)
        self.assertEqual(r.stderr, "")

    def test_fresh_tree_quiet(self):
        r = self.check(0, "--quiet")
        self.assertEqual(r.stdout, "")

    def test_fresh_tree_without_stamp(self):
        (self.gen / ".stamp").unlink()
        self.check(0)

    def test_edited_file(self):
        path = self.gen / "forces" / "tether.h"
        text = path.read_text()
        self.assertIn("Total ops:", text)
        path.write_text(text.replace("Total ops:", "Total ops (edited by hand):", 1))
        r = self.check(1)
        self.assertDrift(r, "cellphys/gen/forces/tether.h")
        self.assertRegex(r.stdout, r"(?m)^-.*Total ops \(edited by hand\):")
        self.assertRegex(r.stdout, r"(?m)^\+.*Total ops: \d+")
        self.assertNotIn("layouts.h", r.stdout)  # only the edited file is reported

    def test_deleted_file(self):
        (self.gen / "force_table.h").unlink()
        r = self.check(1)
        self.assertDrift(r, "cellphys/gen/force_table.h")
        self.assertRegex(r.stdout, r"(?m)^\+inline constexpr ForceInfo kForceTable\[\] = \{")

    def test_extra_file(self):
        write(self.gen / "forces", "stale.h", "// a force that no descriptor declares any more\n")
        r = self.check(1)
        self.assertDrift(r, "cellphys/gen/forces/stale.h")
        self.assertIn("-// a force that no descriptor declares any more", r.stdout)

    def test_descriptor_changed_after_generation(self):
        self.sb = self.__class__.sb.copy_to(temp_dir(self) / "descriptors")
        self.sb.force("tether.yaml", TETHER_FORCE.replace("min: 0, doc", "min: 1, doc"))
        r = self.check(1)
        self.assertDrift(r, "cellphys/gen/force_table.h")

    def test_missing_tree(self):
        shutil.rmtree(self.tree)
        r = self.check(1)
        self.assertIn("+++ fresh/cellphys/gen/layouts.h", r.stdout)
        self.assertIn("scripts/regenerate", r.stderr)

    def test_malformed_descriptor_is_an_error_not_drift(self):
        self.sb = self.__class__.sb.copy_to(temp_dir(self) / "descriptors")
        p = self.sb.force("tether.yaml", TETHER_FORCE.replace("kind: unary", "kind: ternary"))
        r = self.check(2)
        self.assertIn(f"cellphys codegen: error: {p}: kind: unknown kind 'ternary'", r.stderr)

    # regression: emit.diff_tree compares files.get(relpath, "") with the checked-in text (also ""
    # for an empty file), so an extra *empty* file in the checked-in tree is not reported: --check
    # exits 0 although the tree holds a file a fresh generation does not produce (and --out would
    # delete). Compare the file sets, not only the texts.
    def test_extra_empty_file(self):
        write(self.gen / "forces", "stale.h", "")
        r = self.check(1)
        self.assertIn("cellphys/gen/forces/stale.h", r.stdout + r.stderr)


class DefaultForceSetTests(unittest.TestCase):
    """Without --forces the generator reads codegen/descriptors/forces alone: the checked-in generated/ is that
    default generation (the codegen_drift test), so it holds exactly the production forces and no example's."""

    def test_checked_in_tree_holds_the_production_forces_only(self):
        generated = sorted(p.stem for p in (ROOT / "generated/cellphys/gen/forces").glob("*.h"))
        self.assertEqual(generated, sorted(p.stem for p in REAL_FORCES.glob("*.yaml")))
        table = (ROOT / "generated/cellphys/gen/force_table.h").read_text()
        for example in EXAMPLE_FORCES.glob("*.yaml"):
            self.assertNotIn(f'"{example.stem}"', table, f"{example.name} is in the production force table")


if __name__ == "__main__":
    unittest.main()

"""Struct descriptors: good ones lay out as documented, malformed ones stop with file: field: reason."""
import json
import unittest

from codegen_support import DescriptorErrorAssertions, Sandbox, temp_dir, write
from cellphys_codegen.structs import load_struct, load_structs

GOOD_FIELDS = (
    "fields:\n"
    "  - {name: position, type: vec3}\n"
    "  - {name: mass, type: f32}\n"
    "  - {name: id, type: i32}\n"
)


class StructLayoutTests(unittest.TestCase):
    """The positive baseline the error tests below are measured against."""

    def test_good_struct_layout(self):
        d = temp_dir(self)
        p = write(d, "s.yaml", """\
            name: Sample
            align: 16
            fields:
              - {name: mass, type: f32}
              - {name: position, type: vec3}
              - {name: ids, type: u32, count: 3}
              - {name: inertia, type: sym33}
        """)
        s = load_struct(p)
        self.assertEqual(s.name, "Sample")
        self.assertEqual([(f.name, f.offset) for f in s.fields],
                         [("mass", 0), ("position", 16), ("ids", 32), ("inertia", 44)])
        self.assertEqual(s.align, 16)
        self.assertEqual(s.size, 80)  # 44 + 24 = 68, padded to 16
        self.assertEqual(s.paddings, [(4, 12), (68, 12)])

    def test_vec3p_is_three_floats_with_no_padding_lane(self):
        d = temp_dir(self)
        p = write(d, "s.yaml", """\
            name: Sample
            align: 16
            fields:
              - {name: normal, type: vec3}
              - {name: anchor, type: vec3p}
              - {name: hold, type: f32}
        """)
        s = load_struct(p)
        self.assertEqual([(f.name, f.offset, f.size) for f in s.fields],
                         [("normal", 0, 16), ("anchor", 16, 12), ("hold", 28, 4)])
        self.assertEqual(s.size, 32)  # a padded vec3 there would make it 48
        self.assertEqual(s.paddings, [])

    def test_probe_set_generates_its_struct(self):
        sb = Sandbox(temp_dir(self))
        files = sb.render()
        self.assertIn("struct alignas(16) Probe {", files["cellphys/gen/layouts.h"])
        probe = json.loads(files["cellphys/gen/layouts.json"])["Probe"]
        self.assertEqual(probe, {"align": 16, "size": 32, "payload": 28,
                                 "offsets": {"position": 0, "mass": 16, "ids": 20}})


class MalformedStructTests(DescriptorErrorAssertions, unittest.TestCase):
    def setUp(self):
        self.dir = temp_dir(self)

    def check(self, text, field, reason, name="bad.yaml"):
        p = write(self.dir, name, text)
        e = self.assertDescriptorError(lambda: load_structs(self.dir), p, field, reason)
        # the same error through the whole generator
        sb = Sandbox(temp_dir(self))
        q = write(sb.structs, name, text)
        self.assertDescriptorError(sb.render, q, field, reason)
        return e

    def test_missing_name(self):
        self.check("doc: no name\n" + GOOD_FIELDS, "name", r"missing")

    def test_name_not_an_identifier(self):
        self.check("name: 2fast\n" + GOOD_FIELDS, "name", r"not a valid identifier")

    def test_missing_fields(self):
        self.check("name: Thing\nalign: 16\n", "fields", r"missing")

    def test_empty_fields(self):
        self.check("name: Thing\nfields: []\n", "fields", r"non-empty list")

    def test_fields_not_a_list(self):
        self.check("name: Thing\nfields: {position: vec3}\n", "fields", r"non-empty list")

    def test_field_not_a_mapping(self):
        self.check("name: Thing\nfields:\n  - position\n", "fields[0]", r"must be a mapping")

    def test_field_missing_name(self):
        self.check("name: Thing\nfields:\n  - {name: a, type: f32}\n  - {type: f32}\n", "fields[1]", r"missing 'name'")

    def test_field_missing_type(self):
        self.check("name: Thing\nfields:\n  - {name: a}\n", "fields[0]", r"missing 'type'")

    def test_unknown_field_type(self):
        e = self.check("""\
            name: Thing
            fields:
              - {name: a, type: f32}
              - {name: b, type: vec3}
              - {name: c, type: vec5}
        """, "fields[2].type", r"unknown type 'vec5'")
        self.assertIn("mat33", e.reason)  # lists the known types

    def test_duplicate_field_name(self):
        self.check("""\
            name: Thing
            fields:
              - {name: a, type: f32}
              - {name: b, type: f32}
              - {name: a, type: vec3}
        """, "fields[2].name", r"duplicate field 'a'")

    def test_bad_count(self):
        for count, pattern in (("0", r"positive integer, got 0"), ("-2", r"positive integer, got -2"),
                               ("'3'", r"positive integer, got '3'"), ("2.5", r"positive integer, got 2.5"),
                               ("true", r"positive integer, got True")):
            with self.subTest(count=count):
                self.check(f"name: Thing\nfields:\n  - {{name: a, type: f32}}\n  - {{name: b, type: i32, count: {count}}}\n",
                           "fields[1].count", pattern)

    def test_count_on_a_vector_type(self):
        self.check("name: Thing\nfields:\n  - {name: a, type: vec3, count: 2}\n", "fields[0].count",
                   r"only allowed of scalar types")

    def test_unknown_top_level_key(self):
        self.check("name: Thing\ncolour: red\n" + GOOD_FIELDS, "(top level)", r"unknown key\(s\) \['colour'\]")

    def test_unknown_field_key(self):
        self.check("name: Thing\nfields:\n  - {name: a, type: f32, units: m}\n", "fields[0]",
                   r"unknown key\(s\) \['units'\]")

    def test_invalid_yaml(self):
        self.check("name: Thing\nfields: [ {name: a, type: f32\n", "(file)", r"not valid YAML")

    def test_not_a_mapping(self):
        for text in ("", "- name: Thing\n", "just text\n"):
            with self.subTest(text=text):
                self.check(text, "(file)", r"must be a mapping")

    def test_align_not_in_allowed_set(self):
        for align in ("12", "3", "0", "2", "128", "-16", "'16'", "true", "[16]"):
            with self.subTest(align=align):
                self.check(f"name: Thing\nalign: {align}\n" + GOOD_FIELDS, "align", r"must be 4, 8, 16, 32 or 64")

    def test_same_struct_name_in_two_files(self):
        first = write(self.dir, "a_first.yaml", "name: Thing\n" + GOOD_FIELDS)
        second = write(self.dir, "b_second.yaml", "name: Thing\nfields:\n  - {name: x, type: f32}\n")
        e = self.assertDescriptorError(lambda: load_structs(self.dir), second, "name", r"struct 'Thing' is also declared in")
        self.assertIn(str(first), e.reason)


class StructGeneratorBugTests(DescriptorErrorAssertions, unittest.TestCase):
    """Malformed struct descriptors the generator does not yet reject cleanly."""

    def setUp(self):
        self.dir = temp_dir(self)

    # regression: structs.load_struct checks `align not in (4, 8, 16, 32, 64)`, and 16.0 == 16, so a
    # float align passes; Struct.align/size become floats and layouts.h gets `struct alignas(16.0)` and
    # `sizeof(X) == 16.0` (not valid C++), layouts.json records 16.0.
    def test_float_align_is_rejected(self):
        p = write(self.dir, "bad.yaml", "name: Thing\nalign: 16.0\n" + GOOD_FIELDS)
        self.assertDescriptorError(lambda: load_structs(self.dir), p, "align", r"must be 4, 8, 16, 32 or 64")

    # regression: structs.layout does `ftype not in TYPES` on the raw YAML value; a list or mapping
    # is unhashable, so `type: [vec3]` escapes as TypeError: unhashable type: 'list' (a traceback).
    def test_unhashable_field_type_is_a_descriptor_error(self):
        p = write(self.dir, "bad.yaml", "name: Thing\nfields:\n  - {name: a, type: [vec3]}\n")
        self.assertDescriptorError(lambda: load_structs(self.dir), p, "fields[0].type", r"unknown type")

    # regression: structs.layout reports unknown keys with sorted(unknown); with a non-string key
    # (YAML `1: x`) next to a string one, sorted() raises TypeError ('<' between str and int).
    def test_unknown_keys_of_mixed_types_is_a_descriptor_error(self):
        p = write(self.dir, "bad.yaml", "name: Thing\nfields:\n  - {name: a, type: f32, 1: x, units: m}\n")
        self.assertDescriptorError(lambda: load_structs(self.dir), p, "fields[0]", r"unknown key")

    # regression: structs.load_struct (and forces.load_force) call path.read_text() outside the
    # try; a descriptor that is not UTF-8 escapes as UnicodeDecodeError instead of "(file): ...".
    def test_non_utf8_descriptor_is_a_descriptor_error(self):
        p = write(self.dir, "bad.yaml", b"name: Thing\xff\nfields:\n  - {name: a, type: f32}\n")
        self.assertDescriptorError(lambda: load_structs(self.dir), p, "(file)", r".")

    # regression: structs._ident accepts any Python identifier, so C++ keywords pass; a field named
    # `int` becomes `float int;` in layouts.h, which does not compile.
    def test_cxx_keyword_field_name_is_rejected(self):
        p = write(self.dir, "bad.yaml", "name: Thing\nfields:\n  - {name: int, type: f32}\n")
        self.assertDescriptorError(lambda: load_structs(self.dir), p, "fields[0].name", r"int")

    # regression: emit.render appends the generated Island_Params to the struct list without
    # checking the name; a struct descriptor named Island_Params yields two `struct ... Island_Params`
    # definitions in layouts.h (and two "Island_Params" keys in layouts.json, one silently lost).
    def test_struct_named_island_params_is_rejected(self):
        sb = Sandbox(temp_dir(self))
        p = sb.struct("island_params.yaml", "name: Island_Params\nfields:\n  - {name: foo, type: f32}\n")
        self.assertDescriptorError(sb.render, p, "name", r"Island_Params")


if __name__ == "__main__":
    unittest.main()

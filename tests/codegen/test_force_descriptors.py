"""Force descriptors: malformed ones stop generation with DescriptorError(file, field, reason).

Every case is written into a temporary forces dir next to a small good force (pull, which also
provides the island's only global) and rendered through the whole generator (emit.render).
"""
import json
import re
import shutil
import unittest
import warnings

from codegen_support import (REAL_FORCES, TETHER_FORCE, DescriptorError, DescriptorErrorAssertions, Sandbox,
                             UnsupportedExpression, temp_dir)

UNARY = """\
name: probe_force
kind: unary
params:
  stiffness: {type: f32, min: 0}
  anchor: {type: vec3}
"""


def unary(*apply, let=None):
    """A unary force descriptor with params stiffness (f32) and anchor (vec3)."""
    text = UNARY
    if let:
        text += "let:\n" + "".join(f"  {k}: {json.dumps(v)}\n" for k, v in let.items())
    return text + "apply:\n" + "".join(f"  - {json.dumps(a)}\n" for a in apply)


class GoodForceTests(unittest.TestCase):
    def test_tether_generates(self):
        sb = Sandbox(temp_dir(self))
        sb.force("tether.yaml", TETHER_FORCE)
        files = sb.render()
        kernel = files["cellphys/gen/forces/tether.h"]
        self.assertIn("struct Tether_Body_Kernel {", kernel)
        self.assertIn("using Instance = Tether_Force;", kernel)
        self.assertIn("in[0 * stride] = a.position[0];", kernel)
        self.assertRegex(kernel, r"in\[\d+ \* stride\] = f\.stiffness;")
        self.assertRegex(files["cellphys/gen/layouts.h"], r"struct alignas\(16\) Tether_Force \{")

    def test_unary_helper_generates(self):
        # the template the error cases below break: it must be good as written
        sb = Sandbox(temp_dir(self))
        sb.force("probe_force.yaml", unary("force(a, stiffness * (anchor - a.x))", let={"m": "a.mass"}))
        self.assertIn("cellphys/gen/forces/probe_force.h", sb.render())

    def test_step_size_h_is_an_argument_not_an_input(self):
        sb = Sandbox(temp_dir(self))
        sb.force("probe_force.yaml", unary("force(a, stiffness * h * (anchor - a.x))"))
        kernel = sb.render()["cellphys/gen/forces/probe_force.h"]
        self.assertIn("static inline void eval([[maybe_unused]] const S* in, [[maybe_unused]] S h, S* out)", kernel)
        self.assertNotRegex(kernel, r"const S h = in\[")
        self.assertRegex(kernel, r"out\[0\] = .*\bh\b")

    def test_lagged_let_is_held_and_can_be_given(self):
        sb = Sandbox(temp_dir(self))
        sb.force("probe_force.yaml", unary("force(a, stiffness * (anchor - a.x) / s)",
                                           let={"s": "lagged(1 + dot(a.x, a.x))"}))
        kernel = sb.render()["cellphys/gen/forces/probe_force.h"]
        self.assertIn("static constexpr int kHeld = 1;", kernel)
        self.assertIn("const S L_s = held_in ? held_in[0] : S(", kernel)
        self.assertIn("if (held_out) held_out[0] = L_s;", kernel)
        # held: dF/ddelta has no term from differentiating s (only -stiffness / s on the diagonal)
        self.assertNotIn("d_L_s__", kernel)

    def test_real_contact_with_its_struct(self):
        # contact.yaml names the Contact_Force struct descriptor as its instance
        sb = Sandbox(temp_dir(self), real_structs=["contact_force.yaml"])
        shutil.copy(REAL_FORCES / "contact.yaml", sb.forces)
        files = sb.render()
        kernel = files["cellphys/gen/forces/contact.h"]
        self.assertIn("struct Contact_Pair_Kernel {", kernel)
        self.assertIn("struct Contact_World_Kernel {", kernel)
        self.assertIn("using Instance = Contact_Force;", kernel)
        self.assertIn("= f.anchor[2];", kernel)  # the vec3 param read from its 3-float (vec3p) field

    def test_greater_than_is_an_exclusive_lower_bound(self):
        # min: v >= bound; greater_than: v > bound (a divisor, say); both reach the force table
        sb = Sandbox(temp_dir(self))
        sb.force("probe_force.yaml", "name: probe_force\nkind: unary\nparams:\n"
                                     "  stiffness: {type: f32, min: 0, doc: N/m}\n"
                                     "  length: {type: f32, greater_than: 0.5, doc: m}\n"
                                     "globals:\n  probe_speed: {type: f32, default: 1.0, greater_than: 0, doc: m/s}\n"
                                     "apply: ['force(a, stiffness * probe_speed / length * a.x)']\n")
        table = sb.render()["cellphys/gen/force_table.h"]
        self.assertRegex(table, r'\{"stiffness", ParamType::f32, \d+, 1, true, 0\.0f, "N/m"\},')
        self.assertRegex(table, r'\{"length", ParamType::f32, \d+, 1, true, 0\.5f, "m", true\},')
        self.assertRegex(table, r'\{"probe_speed", ParamType::f32, \d+, 1, true, 0\.0f, "m/s", true\}')

    def test_globals_struct_pack_and_scene_places(self):
        sb = Sandbox(temp_dir(self))  # with pull, whose pull_accel sits at pull.accel
        sb.force("probe_force.yaml", "name: probe_force\nkind: unary\n"
                                     "globals:\n  probe_force_speed: {type: f32, default: 2.0, min: 0}\n"
                                     "  spread: {type: vec3, default: [1.0, 2.0, 3.0]}\n"
                                     "apply: ['force(a, probe_force_speed * spread)']\n")
        table = sb.render()["cellphys/gen/force_table.h"]
        self.assertIn("  float probe_force_speed = 2.0f;", table)
        self.assertIn("  float spread[3] = {1.0f, 2.0f, 3.0f};", table)
        self.assertIn("  out.probe_force_speed = in.probe_force_speed;", table)
        self.assertIn("  std::memcpy(out.spread, in.spread, sizeof in.spread);", table)
        self.assertRegex(table, r'\{\{"probe_force_speed", .*\}, \{2\.0f\}, "probe_force\.speed", '
                                r'offsetof\(Force_Globals, probe_force_speed\)\},')
        self.assertIn('"probe_force.spread", offsetof(Force_Globals, spread)}', table)
        self.assertIn('"pull.accel", offsetof(Force_Globals, pull_accel)}', table)

    def test_a_joint_is_marked_in_the_force_table(self):
        # joint: true reaches ForceInfo::joint (the world's collision drops the pairs it joins)
        sb = Sandbox(temp_dir(self))
        for name, joint in (("probe_joint", "joint: true\n"), ("probe_link", "")):
            sb.force(f"{name}.yaml", f"name: {name}\nkind: binary\n{joint}apply: ['force(a, b.x - a.x)', 'force(b, a.x - b.x)']\n")
        table = sb.render()["cellphys/gen/force_table.h"]
        self.assertRegex(table, r'\{"probe_joint", ForceType::probe_joint, ForceKind::binary, false, false, true, ')
        self.assertRegex(table, r'\{"probe_link", ForceType::probe_link, ForceKind::binary, false, false, false, ')

    def test_held_points_reach_the_force_table(self):
        # holds_points names the two vec3 params a joint holds together: their offsets in the
        # instance (vec3s come first in its layout) follow the doc; a joint without has -1, -1
        sb = Sandbox(temp_dir(self))
        sb.force("probe_weld.yaml", "name: probe_weld\nkind: binary\njoint: true\nholds_points: [pa, pb]\n"
                                    "params:\n  k: {type: f32}\n  pa: {type: vec3}\n  pb: {type: vec3}\n"
                                    "apply: ['force(a, k * (b.x - a.x) + pa + pb)', 'force(b, a.x - b.x)']\n")
        sb.force("probe_link.yaml", "name: probe_link\nkind: binary\njoint: true\n"
                                    "apply: ['force(a, b.x - a.x)', 'force(b, a.x - b.x)']\n")
        table = sb.render()["cellphys/gen/force_table.h"]
        self.assertRegex(table, r'\{"probe_weld", ForceType::probe_weld, .*, "", 0, 16\},')
        self.assertRegex(table, r'\{"probe_link", ForceType::probe_link, .*, "", -1, -1\},')

    def test_a_global_shared_by_two_forces_at_a_place_of_its_own(self):
        # two forces declare the same global with the same setting: one field, one place
        sb = Sandbox(temp_dir(self))
        for name in ("probe_one", "probe_two"):
            sb.force(f"{name}.yaml", f"name: {name}\nkind: unary\n"
                                     "globals:\n  probe_gain: {type: f32, default: 3.0, min: 0, setting: probe.gain}\n"
                                     "apply: ['force(a, probe_gain * a.x)']\n")
        table = sb.render()["cellphys/gen/force_table.h"]
        self.assertEqual(table.count("  float probe_gain = 3.0f;"), 1)
        self.assertIn('"probe.gain", offsetof(Force_Globals, probe_gain)}', table)


class MalformedForceTests(DescriptorErrorAssertions, unittest.TestCase):
    def setUp(self):
        self.sb = Sandbox(temp_dir(self), real_structs=["contact_force.yaml"])

    def check(self, text, field, reason, name="probe_force.yaml"):
        p = self.sb.force(name, text)
        return self.assertDescriptorError(self.sb.render, p, field, reason)

    # ---- top level ----
    def test_missing_kind(self):
        self.check("name: probe_force\napply: ['force(a, a.x)']\n", "kind", r"missing")

    def test_missing_apply(self):
        self.check("name: probe_force\nkind: unary\n", "apply", r"missing")

    def test_missing_name(self):
        self.check("kind: unary\napply: ['force(a, a.x)']\n", "name", r"missing")

    def test_name_not_lower_case_identifier(self):
        for name in ("Probe", "probe-force", "1probe", "[probe]"):
            with self.subTest(name=name):
                self.check(f"name: {name}\nkind: unary\napply: ['force(a, a.x)']\n", "name", r"lower_case identifier")

    def test_unknown_kind(self):
        self.check("name: probe_force\nkind: ternary\napply: ['force(a, a.x)']\n", "kind", r"unknown kind 'ternary'")

    def test_unknown_top_level_key(self):
        self.check(unary("force(a, a.x)") + "colour: red\n", "(top level)", r"unknown key\(s\) \['colour'\]")

    def test_invalid_yaml(self):
        self.check("name: probe_force\nkind: unary\napply: [force(a, a.x)\n", "(file)", r"not valid YAML")

    def test_not_a_mapping(self):
        self.check("- name: probe_force\n", "(file)", r"must be a mapping")

    def test_symmetric_not_a_bool(self):
        self.check(unary("force(a, a.x)") + "symmetric: 'yes'\n", "symmetric", r"true or false")

    def test_world_anchor_on_a_unary_force(self):
        self.check(unary("force(a, a.x)") + "world_anchor: true\n", "world_anchor", r"only a binary force")

    def test_joint_on_a_unary_force(self):
        self.check(unary("force(a, a.x)") + "joint: true\n", "joint", r"only a binary force joins two bodies")

    def test_joint_not_a_bool(self):
        self.check("name: probe_force\nkind: binary\njoint: 1\napply: ['force(a, b.x - a.x)']\n", "joint",
                   r"true or false")

    def test_holds_points_of_a_force_that_is_no_joint(self):
        self.check("name: probe_force\nkind: binary\nholds_points: [p, q]\nparams:\n  p: {type: vec3}\n  q: {type: vec3}\n"
                   "apply: ['force(a, p)', 'force(b, q)']\n", "holds_points", r"only a joint")

    def test_holds_points_that_are_not_two_vec3_params(self):
        for held in ("[p]", "[p, k]", "[p, p]", "[p, r]", "p"):
            with self.subTest(held=held):
                self.check("name: probe_force\nkind: binary\njoint: true\nholds_points: " + held +
                           "\nparams:\n  p: {type: vec3}\n  q: {type: vec3}\n  k: {type: f32}\n"
                           "apply: ['force(a, p * k)', 'force(b, q)']\n", "holds_points",
                           r"must name two different vec3 params \(a's point, then b's\) of \['p', 'q'\]")

    def test_world_anchor_on_a_global_force(self):
        self.check("name: probe_force\nkind: global\nworld_anchor: true\napply: ['force(a, a.x)']\n",
                   "world_anchor", r"only a binary force")

    def test_duplicate_force_name_in_two_files(self):
        p = self.sb.force("zz_other.yaml", "name: pull\nkind: unary\napply: ['force(a, a.x)']\n")
        e = self.assertDescriptorError(self.sb.render, p, "name", r"force 'pull' is also declared in")
        self.assertIn("pull.yaml", e.reason)

    # ---- params and globals ----
    def test_unknown_param_type(self):
        self.check(UNARY + "  extra: {type: vec4}\napply: ['force(a, a.x)']\n", "params.extra.type",
                   r"unknown type 'vec4' \(known: f32, vec3\)")

    def test_param_missing_type(self):
        self.check(UNARY + "  extra: {doc: nothing}\napply: ['force(a, a.x)']\n", "params.extra", r"missing 'type'")

    def test_param_unknown_key(self):
        self.check(UNARY + "  extra: {type: f32, max: 3}\napply: ['force(a, a.x)']\n", "params.extra",
                   r"unknown key\(s\) \['max'\]")

    def test_param_min_not_a_number(self):
        self.check(UNARY + "  extra: {type: f32, min: low}\napply: ['force(a, a.x)']\n", "params.extra.min",
                   r"must be a number")

    def test_param_greater_than_not_a_number(self):
        self.check(UNARY + "  extra: {type: f32, greater_than: .nan}\napply: ['force(a, a.x)']\n",
                   "params.extra.greater_than", r"must be a number \(and finite\)")

    def test_param_min_and_greater_than_together(self):
        self.check(UNARY + "  extra: {type: f32, min: 0, greater_than: 0}\napply: ['force(a, a.x)']\n",
                   "params.extra.greater_than", r"give min or greater_than, not both")

    def test_params_not_a_mapping(self):
        self.check("name: probe_force\nkind: unary\nparams: [stiffness]\napply: ['force(a, a.x)']\n", "params",
                   r"must be a mapping")

    def test_reserved_param_names(self):
        for name in ("a", "b", "norm", "force"):
            with self.subTest(name=name):
                self.check(UNARY + f"  {name}: {{type: f32}}\napply: ['force(a, a.x)']\n", f"params.{name}",
                           r"reserved name")

    def test_global_force_with_params(self):
        self.check("name: probe_force\nkind: global\nparams:\n  k: {type: f32}\napply: ['force(a, a.x)']\n",
                   "params", r"global force has no per-instance params")

    def test_param_and_global_with_the_same_name(self):
        self.check(UNARY + "globals:\n  stiffness: {type: f32, default: 1.0}\napply: ['force(a, a.x)']\n",
                   "params", r"\['stiffness'\] declared twice")

    def test_global_default_of_wrong_length(self):
        for gtype, default, lanes in (("vec3", "[0.0, 0.0]", 3), ("vec3", "1.0", 3), ("f32", "[1.0, 2.0, 3.0]", 1),
                                      ("vec3", "[0.0, 0.0, 0.0, 0.0]", 3), ("vec3", "[0.0, x, 0.0]", 3)):
            with self.subTest(type=gtype, default=default):
                self.check(UNARY + f"globals:\n  g: {{type: {gtype}, default: {default}}}\napply: ['force(a, a.x)']\n",
                           "globals.g.default", rf"must be {lanes} number\(s\)")

    def test_global_without_default(self):
        self.check(UNARY + "globals:\n  g: {type: f32}\napply: ['force(a, a.x)']\n", "globals.g.default",
                   r"must be 1 number\(s\), got None")

    def test_global_default_yaml_text_hint(self):
        e = self.check(UNARY + "globals:\n  g: {type: f32, default: 1e5}\napply: ['force(a, a.x)']\n",
                       "globals.g.default", r"got '1e5'")
        self.assertIn("1.0e+5", e.reason)

    def test_global_declared_differently_by_two_forces(self):
        # reported at the later file (forces load in file-name order: pull.yaml, then zz_probe.yaml)
        self.check("name: probe_force\nkind: global\nglobals:\n  pull_accel: {type: vec3, default: [0.0, 0.0, 1.0]}\n"
                   "apply: ['force(a, pull_accel)']\n", "globals.pull_accel", r"also declared differently by .*pull\.yaml",
                   name="zz_probe.yaml")

    def test_global_setting_not_dotted_identifiers(self):
        for bad in ("Probe.gain", "probe..gain", "probe.", "1probe", "[probe]"):
            with self.subTest(setting=bad):
                self.check(UNARY + f"globals:\n  g: {{type: f32, default: 1.0, setting: '{bad}'}}\n"
                           "apply: ['force(a, g * a.x)']\n", "globals.g.setting", r"dotted lower_case identifiers")

    def test_global_shared_at_two_different_settings(self):
        self.sb.force("probe_a.yaml", "name: probe_a\nkind: unary\nglobals:\n"
                      "  probe_gain: {type: f32, default: 1.0, setting: probe.gain}\napply: ['force(a, probe_gain * a.x)']\n")
        self.check("name: probe_force\nkind: unary\nglobals:\n  probe_gain: {type: f32, default: 1.0, setting: probe.other}\n"
                   "apply: ['force(a, probe_gain * a.x)']\n", "globals.probe_gain", r"also declared differently by .*probe_a\.yaml",
                   name="zz_probe.yaml")

    # ---- instance structs ----
    def test_globals_whose_scene_places_collide(self):
        # probe_force at the top of settings, probe_force_speed inside a group of that name
        self.check("name: probe_force\nkind: unary\nglobals:\n  probe_force: {type: f32, default: 1.0}\n"
                   "  probe_force_speed: {type: f32, default: 1.0}\napply: ['force(a, probe_force * probe_force_speed * a.x)']\n",
                   "globals.probe_force_speed", r"settings\.probe_force\.speed collides with settings\.probe_force ")
        # slip and probe_force_slip both at probe_force.slip
        self.check("name: probe_force\nkind: unary\nglobals:\n  slip: {type: f32, default: 1.0}\n"
                   "  probe_force_slip: {type: f32, default: 1.0}\napply: ['force(a, slip * probe_force_slip * a.x)']\n",
                   "globals.probe_force_slip", r"collides with settings\.probe_force\.slip of global slip")

    def test_instance_naming_a_missing_struct(self):
        self.check(unary("force(a, a.x)") + "instance: Nope_Force\n", "instance", r"no struct descriptor named 'Nope_Force'")

    def test_instance_lacking_a_param_field(self):
        text = ("name: probe_force\nkind: binary\ninstance: Contact_Force\nparams:\n  normal: {type: vec3}\n"
                "  stiffness: {type: f32}\napply: ['force(a, stiffness * normal)']\n")
        self.check(text, "params.stiffness", r"struct Contact_Force has no field 'stiffness' of type f32")

    def test_instance_field_of_another_type(self):
        text = "name: probe_force\nkind: binary\ninstance: Contact_Force\nparams:\n  normal: {type: f32}\napply: ['force(a, a.x)']\n"
        self.check(text, "params.normal", r"struct Contact_Force has no field 'normal' of type f32")

    def test_instance_field_vec3p_takes_a_vec3_param_only(self):
        # Contact_Force's anchor is a vec3p: a vec3 param may name it, an f32 param may not
        text = ("name: probe_force\nkind: binary\ninstance: Contact_Force\nparams:\n  anchor: {type: f32}\n"
                "apply: ['force(a, anchor * a.x)']\n")
        self.check(text, "params.anchor", r"struct Contact_Force has no field 'anchor' of type f32")

    def test_instance_lacking_body_fields(self):
        # Probe has no body_a; Tether_Like has body_a but no body_b for a binary force
        self.check("name: probe_force\nkind: unary\ninstance: Probe\nparams:\n  mass: {type: f32}\n"
                   "apply: ['force(a, mass * a.x)']\n", "instance", r"needs an i32 field 'body_a'")
        self.sb.struct("tether_like.yaml", "name: Tether_Like\nfields:\n  - {name: k, type: f32}\n  - {name: body_a, type: i32}\n")
        self.check("name: probe_force\nkind: binary\ninstance: Tether_Like\nparams:\n  k: {type: f32}\n"
                   "apply: ['force(a, k * a.x)']\n", "instance", r"needs an i32 field 'body_b'")

    # ---- expressions ----
    def test_expression_that_does_not_parse(self):
        self.check(unary("force(a, f)", let={"length": "norm(a.x)", "f": "stiffness * (length"}), "let.f",
                   r"does not parse")
        self.check(unary("force(a, a.x)", "force(a, stiffness * (anchor)"), "apply[1]", r"does not parse")

    def test_unknown_name(self):
        self.check(unary("force(a, stifness * a.x)"), "apply[0]", r"unknown name 'stifness'")

    def test_body_b_in_a_unary_force(self):
        self.check(unary("force(b, a.x)"), "apply[0]", r"unknown name 'b'")

    def test_calling_a_non_primitive(self):
        for expr in ("force(a, __import__('os').system('true'))", "force(a, open('/etc/passwd'))",
                     "force(a, vec(exp(stiffness), 0, 0))", "force(a, eval('a.x'))", "force(a, getattr(a, 'x'))",
                     "force(a, (lambda: a.x)())"):
            with self.subTest(expr=expr):
                self.check(unary(expr), "apply[0]", r"only the primitives .* can be called")

    def test_descriptor_expressions_cannot_run_code(self):
        marker = self.sb.root / "pwned"
        for expr in (f"force(a, __import__('os').system('touch {marker}'))",
                     f"force(a, vec(0, 0, 0)) if __import__('os').system('touch {marker}') else force(a, a.x)"):
            with self.subTest(expr=expr):
                with self.assertRaises(DescriptorError):
                    self.sb.force("probe_force.yaml", unary(expr))
                    self.sb.render()
                self.assertFalse(marker.exists())

    def test_disallowed_syntax(self):
        for expr in ("force(a, a.x[0] * a.x)", "force(a, a.x if stiffness > 0 else anchor)",
                     "force(a, [k for k in a.x])", "force(a, stiffness == 1)", "force(a, (a.x, anchor))"):
            with self.subTest(expr=expr):
                self.check(unary(expr), "apply[0]", r"is not allowed in")

    def test_non_numeric_constant(self):
        self.check(unary("force(a, vec('1', 0, 0))"), "apply[0]", r"constant '1' is not a number")

    def test_chained_comparison(self):
        self.check(unary("force(a, where(0 < stiffness < 1, a.x, anchor))"), "apply[0]", r"chained comparisons")

    def test_attribute_access_other_than_body_state(self):
        for expr, pattern in (("force(a, a.__class__)", r"a body has no attribute '__class__'"),
                              ("force(a, a.R * a.x)", r"a body has no attribute 'R'"),
                              ("force(a, a.x0)", r"a body has no attribute 'x0'"),
                              ("force(a, anchor.T)", r"attributes are only read from bodies"),
                              ("force(a, stiffness.func)", r"attributes are only read from bodies"),
                              ("force(a, a.x.__class__)", r"attributes are only read from bodies"),
                              ("force(a, vec(1, 2, 3).T)", r"attributes are only read from bodies")):
            with self.subTest(expr=expr):
                self.check(unary(expr), "apply[0]", pattern)

    def test_let_not_a_mapping(self):
        self.check(UNARY + "let: [x]\napply: ['force(a, a.x)']\n", "let", r"must be a mapping")

    def test_let_shadowing_a_name(self):
        for name in ("stiffness", "a", "norm"):
            with self.subTest(name=name):
                self.check(unary("force(a, a.x)", let={name: "a.mass"}), f"let.{name}", r"not a free identifier")

    def test_let_that_is_neither_number_nor_vector(self):
        for expr in ("a", "inertia_world(a)", "stiffness > 0"):
            with self.subTest(expr=expr):
                self.check(unary("force(a, a.x)", let={"q": expr}), "let.q", r"neither a number nor a vector")

    # ---- apply ----
    def test_apply_not_a_non_empty_list(self):
        for apply in ("[]", "'force(a, a.x)'", "{f: 'force(a, a.x)'}"):
            with self.subTest(apply=apply):
                self.check(UNARY + f"apply: {apply}\n", "apply", r"non-empty list")

    def test_apply_entry_not_a_contribution(self):
        for expr in ("world_point(a, anchor)", "anchor", "stiffness", "5", "a"):
            with self.subTest(expr=expr):
                self.check(unary("force(a, a.x)", expr), "apply[1]",
                           r"is not force\(\.\.\.\), torque\(\.\.\.\) or force_at_point\(\.\.\.\)")

    def test_apply_entry_not_an_expression(self):
        self.check(UNARY + "apply:\n  - force(a, a.x)\n  - null\n", "apply[1]", r"expected an expression string")

    def test_scalar_where_a_vector_is_needed(self):
        for expr, what in (("force(a, stiffness)", "force"), ("torque(a, a.mass)", "torque"),
                           ("force(a, vec(1, 2))", "force"), ("torque(a, inertia_world(a))", "torque"),
                           ("force_at_point(a, a.x, stiffness)", None)):
            with self.subTest(expr=expr):
                self.check(unary(expr), "apply[0]",
                           rf"the {what} in .* is not a 3-vector" if what else r"cannot evaluate|not a 3-vector")

    def test_vector_where_a_scalar_is_needed(self):
        for expr in ("force(a, vec(sqrt(a.x), 0, 0))", "force(a, vec(max(a.x, 1), 0, 0))",
                     "force(a, vec(anchor, 0, 0))", "force(a, where(a.x > 0, a.x, anchor))",
                     "force(a, positive_part(a.x))", "force(a, a.x * a.x)", "force(a, anchor / a.x)"):
            with self.subTest(expr=expr):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # SymPy deprecations on non-Expr matrix entries
                    self.check(unary(expr), "apply[0]", r"cannot evaluate|not a 3-vector")

    def test_wrong_arguments_to_primitives(self):
        for expr, pattern in (("force(stiffness, a.x)", r"takes a body"), ("force(a)", r"missing 1 required"),
                              ("force(a, a.x, a.v)", r"positional argument"), ("norm(stiffness)", r"cannot evaluate"),
                              ("force(a, cross(a.x, vec(1, 2)))", r"cannot evaluate")):
            with self.subTest(expr=expr):
                self.check(unary(expr), "apply[0]", pattern)

    def test_inertia_of_the_world(self):
        text = ("name: probe_force\nkind: binary\nworld_anchor: true\n"
                "apply: ['torque(b, inertia_world(b) * a.w)']\n")
        self.check(text, "apply[0]", r"inertia_world\(\) of the world is undefined")

    def test_not_differentiable(self):
        self.check(unary("force(a, vec(stiffness / (a.mass - a.mass), 0, 0))"), "apply", r"not differentiable")

    def test_not_emittable_power(self):
        # x**1.7 differentiates fine but has no vectorisable C++ form (cxx_printer._pow)
        self.sb.force("probe_force.yaml", unary("force(a, vec(stiffness**1.7, 0, 0))"))
        with self.assertRaises((DescriptorError, UnsupportedExpression)) as cm:
            self.sb.render()
        self.assertIn("power", str(cm.exception))
        self.assertIn("1.7", str(cm.exception))


class ForceGeneratorBugTests(DescriptorErrorAssertions, unittest.TestCase):
    """Force descriptors the generator does not yet handle correctly."""

    def setUp(self):
        self.sb = Sandbox(temp_dir(self), real_structs=["contact_force.yaml"])

    def render_kernel(self, name, text):
        self.sb.force(f"{name}.yaml", text)
        return self.sb.render()[f"cellphys/gen/forces/{name}.h"]

    def assertNoDuplicateDeclarations(self, kernel):
        for body in re.findall(r"static inline void eval\(.*?\n  \}", kernel, re.S):
            decls = re.findall(r"const S (\w+) =", body)
            dup = sorted({d for d in decls if decls.count(d) > 1})
            self.assertEqual(dup, [], "declared twice in one eval()")

    # regression: forces._build_kernel adds each apply contribution with
    # `F[k] += sp.Matrix.vstack(...)` outside evaluate()'s try; a comparison inside a vector
    # (`vec(a.mass > 1, 0, 0)`) evaluates to a Matrix of Relationals and the addition raises
    # TypeError: bad operand type for unary +: 'StrictGreaterThan' (a traceback, exit 1).
    def test_comparison_inside_a_vector_is_a_descriptor_error(self):
        p = self.sb.force("probe_force.yaml", unary("force(a, vec(a.mass > 1, 0, 0))"))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.assertDescriptorError(self.sb.render, p, "apply[0]", r".")

    # regression: forces._instance_struct does `structs.get(d["instance"])` on the raw YAML value;
    # `instance: [Contact_Force]` raises TypeError: unhashable type: 'list'.
    def test_unhashable_instance_is_a_descriptor_error(self):
        p = self.sb.force("probe_force.yaml", unary("force(a, a.x)") + "instance: [Contact_Force]\n")
        self.assertDescriptorError(self.sb.render, p, "instance", r"no struct descriptor")

    # regression: forces.load_force (and forces._params, structs.load_struct, structs.layout) report
    # unknown keys with sorted(unknown); an int key (YAML `1: x`) next to a string key makes sorted()
    # raise TypeError: '<' not supported between instances of 'str' and 'int'.
    def test_unknown_keys_of_mixed_types_is_a_descriptor_error(self):
        p = self.sb.force("probe_force.yaml", unary("force(a, a.x)") + "1: x\ncolour: red\n")
        self.assertDescriptorError(self.sb.render, p, "(top level)", r"unknown key")

    # regression: forces._build_kernel names lane i of a vec3 param `p_<name><i>`, so a vec3 param
    # `v` and an f32 param `v0` are both the SymPy symbol p_v0 (one symbol): eval() declares
    # `const S p_v0` twice and `v + vec(v0, 0, 0)` is generated as 2*p_v0 (silently wrong math).
    def test_param_lane_names_do_not_collide(self):
        text = ("name: probe_force\nkind: unary\nparams:\n  v: {type: vec3}\n  v0: {type: f32}\n"
                "apply: ['force(a, v + vec(v0, 0, 0))']\n")
        try:
            kernel = self.render_kernel("probe_force", text)
        except DescriptorError as e:  # rejecting the pair is a fix too
            self.assertIn("v0", str(e))
            return
        self.assertNoDuplicateDeclarations(kernel)
        self.assertNotRegex(kernel, r"out\[0\] = \(S\(2\)\*p_v0\);")

    # regression: the same collision for lets: a vector let `x` is L_x0..L_x2 and a scalar let `x0`
    # is L_x0 again; eval() declares `const S L_x0` twice and the force uses the wrong value.
    def test_let_lane_names_do_not_collide(self):
        text = ("name: probe_force\nkind: unary\nlet:\n  x: a.v * 2\n  x0: a.mass\n"
                "apply: ['force(a, x * x0)']\n")
        try:
            kernel = self.render_kernel("probe_force", text)
        except DescriptorError as e:
            self.assertIn("x0", str(e))
            return
        self.assertNoDuplicateDeclarations(kernel)

    # regression: params (and globals, let) are YAML mappings read with yaml.safe_load, which keeps
    # the last of two equal keys; a param declared twice (vec3 then f32) is silently the f32 one
    # instead of a "declared twice" error.
    def test_duplicate_key_in_params_is_rejected(self):
        p = self.sb.force("probe_force.yaml", "name: probe_force\nkind: unary\nparams:\n  k: {type: vec3}\n"
                                              "  k: {type: f32}\napply: ['force(a, k * a.x)']\n")
        with self.assertRaises(DescriptorError) as cm:
            self.sb.render()
        self.assertEqual(cm.exception.path, str(p))
        self.assertIn("k", cm.exception.reason)

    # regression: a force without `instance:` gets a derived instance struct <Camel>_Force, but
    # emit.render only adds it to layouts.h when no struct descriptor has that name; if one does
    # (here Tether_Force with another layout), layouts.h defines the descriptor's struct while
    # force_table.h's ParamInfo offsets come from the derived layout -- silently inconsistent.
    def test_derived_instance_clashing_with_a_struct_descriptor_is_rejected(self):
        self.sb.struct("tether_force.yaml", "name: Tether_Force\nfields:\n  - {name: body_a, type: i32}\n"
                                            "  - {name: stiffness, type: f32}\n  - {name: anchor, type: vec3}\n")
        self.sb.force("tether.yaml", TETHER_FORCE)
        with self.assertRaises(DescriptorError) as cm:
            self.sb.render()
        self.assertIn("Tether_Force", str(cm.exception))

    # regression: doc strings go into C++ unescaped (templates force_table.h.j2 `"{{ f.doc }}"`,
    # `"{{ p.doc }}"`, force_kernel.h.j2 `// {{ force.doc }}`, layouts.h.j2 `/// {{ s.doc }}`); a doc
    # with a double quote ends the string literal early and a doc with a newline (YAML "\n" or a |
    # block) continues outside the comment/literal: the generated headers do not compile.
    def test_doc_with_quote_and_newline_is_escaped_or_rejected(self):
        doc = 'say "hi"\nsecond line'
        text = unary("force(a, stiffness * a.x)") + 'doc: "say \\"hi\\"\\nsecond line"\n'
        p = self.sb.force("probe_force.yaml", text)
        try:
            files = self.sb.render()
        except DescriptorError as e:
            self.assertEqual((e.path, e.field), (str(p), "doc"))
            return
        for name, body in files.items():
            for line in body.splitlines():
                self.assertFalse(line.lstrip().startswith("second line"), f"{name}: doc newline breaks out")
        entry = next(l for l in files["cellphys/gen/force_table.h"].splitlines() if '{"probe_force", ForceType' in l)
        literals = [re.sub(r'\\(.)', lambda m: {"n": "\n"}.get(m.group(1), m.group(1)), s[1:-1])
                    for s in re.findall(r'"(?:[^"\\\n]|\\.)*"', entry)]
        self.assertIn(doc, literals)

    # regression: forces.load_force checks the force name with str.isidentifier() only; C++
    # keywords pass, so `name: delete` generates `enum class ForceType { delete = 1 }` and
    # `ForceType::delete` (param and let names have the same problem), which does not compile.
    def test_cxx_keyword_force_name_is_rejected(self):
        p = self.sb.force("delete.yaml", "name: delete\nkind: unary\napply: ['force(a, a.x)']\n")
        self.assertDescriptorError(self.sb.render, p, "name", r"delete")

    # regression: forces._params accepts any float default/min, including YAML .nan and .inf; the
    # template prints them as `nanf` / `inff` in force_table.h (default_island_params, kGlobalTable),
    # which are not C++ literals.
    def test_non_finite_global_default_is_rejected(self):
        for default in (".nan", ".inf", "[0.0, -.inf, 0.0]"):
            with self.subTest(default=default):
                gtype, use = ("vec3", "a.mass * g") if default.startswith("[") else ("f32", "g * a.x")
                p = self.sb.force("probe_force.yaml", UNARY + f"globals:\n  g: {{type: {gtype}, default: {default}}}\n"
                                                              f"apply: ['force(a, {use})']\n")
                self.assertDescriptorError(self.sb.render, p, "globals.g.default", r".")

    # regression: emit.render always lays out Island_Params with structs.layout(), which rejects an
    # empty field list, so a force set in which no force declares a global (e.g. damping.yaml or
    # air_drag.yaml alone) cannot be generated: DescriptorError "(globals): fields: must be a non-empty
    # list of fields" -- not a file, and not an error in any descriptor.
    def test_force_set_without_globals_generates(self):
        sb = Sandbox(temp_dir(self), probe=False)
        sb.force("tether.yaml", TETHER_FORCE)
        files = sb.render()
        self.assertIn("Island_Params", files["cellphys/gen/layouts.h"])
        self.assertIn("cellphys/gen/forces/tether.h", files)


if __name__ == "__main__":
    unittest.main()

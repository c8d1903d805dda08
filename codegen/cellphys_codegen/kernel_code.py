"""A force kernel's entry points as statements (statements.py), each naming the let or apply
entry of the descriptor it comes from, so a wrong kernel can be traced to its line of YAML."""
from dataclasses import replace

from . import cxx_printer
from . import statements as st
from .errors import DescriptorError

AB = "ab"


def _preamble(k):
    if not k.pre:
        return [], 0
    users = ", ".join(dict.fromkeys(k.pre_origins.values()))
    return st.stage(list(k.pre.items()), "p0_", f"body-frame quantities rotated to world, first used by {users}")


def _acting_on(k, body):
    entries = [origin for origin, b in k.applies if b == body]
    return ", ".join(entries) if entries else "no apply entry"


def _eval_groups(k):
    groups = [(6, f"F_{AB[i]} from {_acting_on(k, i)}") for i in range(k.num_bodies)]
    groups += [(36, f"dF_{AB[b.row_body]}/d{'delta' if b.kind == 'dd' else 'u'}_{AB[b.col_body]} from "
                    f"{_acting_on(k, b.row_body)}") for b in k.blocks]
    return groups


def _implicit_groups(k):
    groups = [(6, f"g_{AB[i]} from {_acting_on(k, i)}") for i in range(k.num_bodies)]
    groups += [(36, f"K_{AB[i]}{AB[j]} from {_acting_on(k, i)}") for i, j in k.implicit["pairs"]]
    return groups


def _gather(k):
    f = k.force
    code = []
    for idx, inp in enumerate(k.inputs):
        if inp.source == "body" and inp.name.startswith("ref_"):
            # reference pose: from the caller's array (x y z _ w x y z per body), else the current pose
            tag = AB[inp.body]
            cur = "position" if inp.name == "ref_position" else "orientation"
            lane = inp.lane + (0 if cur == "position" else 4)
            src = f"ref ? ref[8 * f.body_{tag} + {lane}] : {tag}.{cur}[{inp.lane}]"
        elif inp.source == "body":
            fld = inp.name
            src = f"{AB[inp.body]}.{fld}[{inp.lane}]" if fld not in ("mass",) else f"{AB[inp.body]}.{fld}"
        elif inp.source == "param":
            p = next(p for p in f.params if p.name == inp.name)
            src = f"f.{inp.name}[{inp.lane}]" if p.lanes > 1 else f"f.{inp.name}"
        else:
            p = next(p for p in f.globals if p.name == inp.name)
            src = f"g.{inp.name}[{inp.lane}]" if p.lanes > 1 else f"g.{inp.name}"
        code.append(st.Statement("output", "", f"in[{idx} * stride]", src))
    return code


def _view(k):
    inputs = [st.Statement("input", "S", inp.symbol.name, f"in[{idx}]", maybe_unused=True)
              for idx, inp in enumerate(k.inputs)]
    pre, pre_ops = _preamble(k)
    # eval and eval_implicit: every let with its derivatives; a held value only the F-only path
    # reads back (e.g. the world side's zero lever arm)
    lets, let_ops = [], 0
    for i, s in enumerate(k.stages):
        code, n = st.stage(s.items, f"l{i}_0_", s.origin, s.held)
        lets += [replace(c, maybe_unused=True) if c.held else c for c in code]
        let_ops += n
    # eval_f (explicit integrators, a Rosenbrock method's second stage): the lets' values alone. A
    # lagged() let can be read from held_in (the values at another state: the Jacobian tests
    # difference F with the held values fixed, as the linearisation holds them) and is written to
    # held_out
    f_lets, f_let_ops, num_held = [], 0, 0
    for i, s in enumerate(k.stages):
        values = [(sym, e) for sym, e in s.items if not sym.name.startswith("d_")]
        code, n = st.stage(values, f"l{i}_0_", s.origin, s.held)
        for c in code:
            if c.held:
                c = replace(c, slot=num_held)
                num_held += 1
            f_lets.append(c)
        f_let_ops += n
    slots = {c.name: c.slot for c in f_lets if c.held}
    joint_arms = [slots[k.joint_arms[b][0].name] if b in k.joint_arms else -1 for b in range(k.num_bodies)]
    for b, syms in k.joint_arms.items():  # the arm's lanes and its share are consecutive slots
        assert [slots[x.name] for x in syms] == list(range(joint_arms[b], joint_arms[b] + 4)), syms
    shared = f"{k.apply_origin}, shared subexpressions"
    blocks = [e for b in k.blocks for e in b.exprs]
    outs, out_ops = st.outputs(k.forces + blocks, "out", _eval_groups(k), shared)
    f_outs, f_out_ops = st.outputs(k.forces, "out", _eval_groups(k)[:k.num_bodies], shared)
    i_outs, i_out_ops = st.outputs(k.implicit["outputs"], "out", _implicit_groups(k), shared)
    # the implicit form's products taken on the lets the forces read, where that costs less
    through = k.implicit.get("through_lets")
    if through:
        t_lets, t_ops = st.stage(through["lets"], "t0_", f"{k.apply_origin}, the implicit form's products on its lets")
        t_outs, t_out_ops = st.outputs(through["outputs"], "out", _implicit_groups(k), shared)
        if t_ops + t_out_ops < i_out_ops:
            i_outs, i_out_ops = t_lets + t_outs, t_ops + t_out_ops
    return dict(
        name=k.cxx_name, variant=k.variant, num_bodies=k.num_bodies, num_inputs=len(k.inputs), gather=_gather(k),
        blocks=[dict(kind=b.kind, row=b.row_body, col=b.col_body) for b in k.blocks],
        num_outputs=len(k.forces) + len(blocks), num_held=num_held, joint_arms=joint_arms,
        i_pairs=k.implicit["pairs"], i_outputs=len(k.implicit["outputs"]),
        uses_b=any(i.source == "body" and i.body == 1 for i in k.inputs),
        code=inputs + pre + lets + outs, ops=pre_ops + let_ops + out_ops,
        i_code=inputs + pre + lets + i_outs, i_ops=pre_ops + let_ops + i_out_ops,
        f_code=inputs + pre + f_lets + f_outs, f_ops=pre_ops + f_let_ops + f_out_ops,
    )


def kernel_view(f, k):
    """The template's view of kernel k of force f."""
    try:
        return _view(k)
    except cxx_printer.UnsupportedExpression as e:
        raise DescriptorError(f.source, "apply", str(e)) from None

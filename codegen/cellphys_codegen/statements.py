"""Straight-line C++ as data: every statement's kind, type, name and expression, and the
descriptor entry it comes from. templates/util/util.jinja prints them all; nothing reads the
printed C++ back."""
from dataclasses import dataclass

from . import cxx_printer


@dataclass(frozen=True)
class Statement:
    kind: str  # "input", "temporary", "value" (of a symbol: a let, a derivative, a preamble quantity) or "output"
    type: str  # "S", or "auto" for a lane mask CSE pulled out of a condition; "" for an output
    name: str  # what it declares, or where an output is written ("out[3]")
    expr: str  # the C++ expression
    origin: str = None  # the descriptor entry it comes from, e.g. "let depth (contact.yaml:27)"
    held: bool = False  # the value of a lagged() let, held through the step
    slot: int = None  # a held value the caller may give instead: its index in held_in and held_out
    maybe_unused: bool = False  # read by some entry points only


def stage(items, prefix, origin=None, held=False):
    """[(symbol, expression)] CSE'd on its own: its temporaries, then the symbols' values; and the op count."""
    tmps, outs, ops = cxx_printer.emit([e for _, e in items], prefix)
    code = [Statement("temporary", ty, t, c, origin) for ty, t, c in tmps]
    code += [Statement("value", "S", sym.name, c, origin, held=held) for (sym, _), c in zip(items, outs)]
    return code, ops


def stages(stage_list, prefix):
    """Each stage CSE'd on its own, in order (temporaries named prefix<k>_...); and the op count."""
    code, ops = [], 0
    for k, items in enumerate(stage_list):
        c, n = stage(items, f"{prefix}{k}_")
        code += c
        ops += n
    return code, ops


def outputs(exprs, target, groups, origin):
    """exprs CSE'd together and written to target[0], target[1], ...; and the op count.

    The temporaries carry `origin`; groups [(count, origin)] name the outputs in order."""
    tmps, outs, ops = cxx_printer.emit(exprs, "o")
    code = [Statement("temporary", ty, t, c, origin) for ty, t, c in tmps]
    names = [o for count, o in groups for _ in range(count)]
    assert len(names) == len(outs), "the output groups must cover every output"
    code += [Statement("output", "", f"{target}[{i}]", c, o) for i, (c, o) in enumerate(zip(outs, names))]
    return code, ops

"""Struct descriptors -> packed layouts: every size, offset and padding byte is computed here."""
from dataclasses import dataclass, field
from pathlib import Path

from . import names as naming
from . import yaml_loader
from .errors import DescriptorError

# type -> (bytes, alignment, C element type, stored floats, logical floats)
# vec3/quat/mat33 rows are stored as 4 floats so one row is one 128-bit register (the reference design's padding).
# vec3p is a vec3 stored as its 3 floats: for a record its kernels read lane by lane, where a padding
# lane would grow it by its alignment (the contact's friction anchor beside its hold).
TYPES = {
    "f32": (4, 4, "float", 1, 1),
    "i32": (4, 4, "int32_t", 1, 1),
    "u32": (4, 4, "uint32_t", 1, 1),
    "vec3": (16, 16, "float", 4, 3),
    "vec3p": (12, 4, "float", 3, 3),
    "quat": (16, 16, "float", 4, 4),
    "vec4": (16, 16, "float", 4, 4),
    "sym33": (24, 4, "float", 6, 6),
    "mat33": (48, 16, "float", 12, 9),
}


@dataclass
class Field:
    name: str
    type: str
    count: int
    offset: int
    size: int
    align: int
    ctype: str
    stored: int  # elements stored (with padding lanes)
    logical: int  # elements that carry data
    doc: str = ""

    @property
    def is_scalar(self):
        return self.count == 1 and self.stored == 1


@dataclass
class Struct:
    name: str
    doc: str
    align: int
    size: int
    fields: list
    source: str
    paddings: list = field(default_factory=list)  # (offset, bytes) of padding runs

    def field(self, name):
        for f in self.fields:
            if f.name == name:
                return f
        return None

    @property
    def payload_bytes(self):
        return sum(4 * f.logical * f.count for f in self.fields)


def _ident(path, where, text, kind):
    why = naming.problem(text, kind)
    if why:
        raise DescriptorError(path, where, why)
    return text


def unknown_keys(d, allowed):
    return sorted((k for k in d if k not in allowed), key=str)


def layout(name, doc, align, raw_fields, path, where="fields", allow_empty=False):
    """Lay fields out in declared order, each at its natural alignment; pad the tail to `align`."""
    offset, fields, pads, seen = 0, [], [], set()
    if not isinstance(raw_fields, list) or (not raw_fields and not allow_empty):
        raise DescriptorError(path, where, "must be a non-empty list of fields")
    for i, rf in enumerate(raw_fields):
        loc = f"{where}[{i}]"
        if not isinstance(rf, dict):
            raise DescriptorError(path, loc, "must be a mapping with name and type")
        unknown = unknown_keys(rf, {"name", "type", "count", "doc"})
        if unknown:
            raise DescriptorError(path, loc, f"unknown key(s) {unknown}")
        if "name" not in rf:
            raise DescriptorError(path, loc, "missing 'name'")
        fname = _ident(path, f"{loc}.name", rf["name"], "field")
        if fname in seen:
            raise DescriptorError(path, f"{loc}.name", f"duplicate field {fname!r}")
        seen.add(fname)
        if "type" not in rf:
            raise DescriptorError(path, f"{loc}", f"field {fname!r} is missing 'type'")
        ftype = rf["type"]
        if not isinstance(ftype, str) or ftype not in TYPES:
            raise DescriptorError(path, f"{loc}.type", f"unknown type {ftype!r} (known: {', '.join(TYPES)})")
        count = rf.get("count", 1)
        if not isinstance(count, int) or isinstance(count, bool) or count < 1:
            raise DescriptorError(path, f"{loc}.count", f"must be a positive integer, got {count!r}")
        if count > 1 and TYPES[ftype][3] != 1:
            raise DescriptorError(path, f"{loc}.count", "arrays are only allowed of scalar types (f32, i32, u32)")
        size, falign, ctype, stored, logical = TYPES[ftype]
        size *= count
        aligned = (offset + falign - 1) // falign * falign
        if aligned != offset:
            pads.append((offset, aligned - offset))
        fields.append(Field(fname, ftype, count, aligned, size, falign, ctype, stored, logical, rf.get("doc", "")))
        offset = aligned + size
    struct_align = max([align] + [f.align for f in fields])
    if not fields:  # an empty struct still has a size: one aligned block of padding
        offset = struct_align
        pads.append((0, struct_align))
    total = (offset + struct_align - 1) // struct_align * struct_align
    if total != offset:
        pads.append((offset, total - offset))
    return Struct(name, doc, struct_align, total, fields, str(path), pads)


def load_struct(path):
    path = Path(path)
    d = yaml_loader.load(path)
    if not isinstance(d, dict):
        raise DescriptorError(path, "(file)", "must be a mapping")
    unknown = unknown_keys(d, {"name", "doc", "align", "fields"})
    if unknown:
        raise DescriptorError(path, "(top level)", f"unknown key(s) {unknown}")
    if "name" not in d:
        raise DescriptorError(path, "name", "missing")
    name = _ident(path, "name", d["name"], "struct")
    align = d.get("align", 4)
    if isinstance(align, bool) or not isinstance(align, int) or align not in (4, 8, 16, 32, 64):
        raise DescriptorError(path, "align", f"must be 4, 8, 16, 32 or 64, got {align!r}")
    if "fields" not in d:
        raise DescriptorError(path, "fields", "missing")
    return layout(name, d.get("doc", ""), align, d["fields"], path)


def load_structs(directory):
    structs = [load_struct(p) for p in sorted(Path(directory).glob("*.yaml"))]
    names = {}
    for s in structs:
        if s.name in names:
            raise DescriptorError(s.source, "name", f"struct {s.name!r} is also declared in {names[s.name]}")
        names[s.name] = s.source
    return structs

"""Names a descriptor may not use: C++ keywords and the names the generator itself emits."""
import re

CXX_KEYWORDS = frozenset("""
alignas alignof and and_eq asm auto bitand bitor bool break case catch char char8_t char16_t
char32_t class compl concept const consteval constexpr constinit const_cast continue co_await
co_return co_yield decltype default delete do double dynamic_cast else enum explicit export
extern false float for friend goto if inline int long mutable namespace new noexcept not not_eq
nullptr operator or or_eq private protected public register reinterpret_cast requires return
short signed sizeof static static_assert static_cast struct switch template this thread_local
throw true try typedef typeid typename union unsigned using virtual void volatile wchar_t while
xor xor_eq int8_t int16_t int32_t int64_t uint8_t uint16_t uint32_t uint64_t size_t
""".split())

RESERVED_TYPES = frozenset({"Island_Params", "Force_Globals", "StructInfo", "ParamInfo", "GlobalInfo", "ForceInfo", "BlockSlot",
                            "ForceType", "ForceKind", "KernelVariant", "BlockKind", "ParamType"})


def problem(name, kind):
    """Why `name` cannot name a `kind` ("field", "struct", "force", "param", "let"), or None."""
    if not isinstance(name, str) or not name.isidentifier():
        return f"{name!r} is not a valid identifier"
    if name in CXX_KEYWORDS:
        return f"{name!r} is a C++ keyword"
    if "__" in name or name.startswith("_"):
        return f"{name!r}: names may not start with '_' or contain '__' (reserved for generated code)"
    if kind == "field" and re.fullmatch(r"pad_\d+", name):
        return f"{name!r} is reserved for generated padding"
    if kind == "struct" and (name in RESERVED_TYPES or name.endswith("_Fields")):
        return f"{name!r} is reserved for a generated type"
    return None

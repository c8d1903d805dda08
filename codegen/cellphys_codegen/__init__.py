"""cellphys code generator: descriptors (YAML) -> SymPy -> Jinja2 -> C++ headers."""

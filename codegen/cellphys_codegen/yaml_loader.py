"""YAML reading for descriptors: duplicate keys are errors, and so are unreadable files."""
import yaml

from .errors import DescriptorError


class _StrictLoader(yaml.SafeLoader):
    pass


def _mapping(loader, node, deep=False):
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:
            continue  # unhashable keys are reported by the schema checks
        if duplicate:
            raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep=deep)


_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping)


def _note_lines(node, where, lines):
    """The 1-based line of every mapping key and sequence item below node, by field as errors name
    it ("let.depth", "apply[0]")."""
    if isinstance(node, yaml.MappingNode):
        for key_node, value_node in node.value:
            if isinstance(key_node, yaml.ScalarNode):
                field = f"{where}.{key_node.value}" if where else key_node.value
                lines[field] = key_node.start_mark.line + 1
                _note_lines(value_node, field, lines)
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            field = f"{where}[{i}]"
            lines[field] = item.start_mark.line + 1
            _note_lines(item, field, lines)


def load_with_lines(path):
    """(the document, {field: line}) of a descriptor file: generated code names the line it comes from."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise DescriptorError(path, "(file)", f"cannot be read as UTF-8 text: {e}") from None
    loader = _StrictLoader(text)
    try:
        node = loader.get_single_node()
        data = loader.construct_document(node) if node is not None else None
    except yaml.YAMLError as e:
        raise DescriptorError(path, "(file)", f"not valid YAML: {e}") from None
    finally:
        loader.dispose()
    lines = {}
    _note_lines(node, "", lines)
    return data, lines


def load(path):
    return load_with_lines(path)[0]

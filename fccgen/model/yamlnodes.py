"""YAML text -> plain values that remember their line.

The model loader needs the line of every value to say where a rule is broken, and it
must reject what PyYAML silently accepts (a repeated key keeps only its last value).
So the text is *composed* into PyYAML's node tree with a safe loader, and that tree is
walked here into three small node types:

* :class:`YScalar` -- a scalar: its safely constructed value and its source text;
* :class:`YSeq`    -- a sequence of nodes;
* :class:`YMap`    -- a mapping from key text to node, with the line of every key.

Lines are 1-based. Scalars are built only by :class:`yaml.SafeLoader`'s constructors;
nothing from the file reaches ``eval`` or an arbitrary Python constructor.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Union

import yaml

from ..errors import ModelError

# YAML 1.2 floats with an exponent (1e-3, 5E+2, 2.5e3): PyYAML's YAML 1.1 resolver
# wants a dot and a signed exponent, and reads these as strings otherwise.
FLOAT_12 = re.compile(r"^[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)[eE][-+]?[0-9]+$")

MAP_TAG = "tag:yaml.org,2002:map"
# Scalar tags the safe loader builds (explicit or resolved); any other tag is refused.
SCALAR_TAGS = frozenset(f"tag:yaml.org,2002:{t}" for t in
                        ("null", "bool", "int", "float", "str", "timestamp", "binary"))
SEQ_TAG = "tag:yaml.org,2002:seq"


class ModelLoader(yaml.SafeLoader):
    """Safe loader that also reads YAML 1.2 exponent floats as floats."""


ModelLoader.add_implicit_resolver("tag:yaml.org,2002:float", FLOAT_12,
                                  list("-+0123456789."))


@dataclass(frozen=True, eq=False)
class YScalar:
    value: object          # str, int, float, bool, None (or another safe YAML scalar)
    text: str              # the scalar as written (without quotes)
    line: int

    def plain(self):
        return self.value


@dataclass(frozen=True, eq=False)
class YSeq:
    items: tuple["YNode", ...]
    line: int

    def plain(self):
        return [n.plain() for n in self.items]


@dataclass(frozen=True, eq=False)
class YMap:
    entries: dict[str, "YNode"]     # key text -> value node, in file order
    key_lines: dict[str, int]       # key text -> line of the key
    line: int

    def plain(self):
        return {k: n.plain() for k, n in self.entries.items()}


YNode = Union[YScalar, YSeq, YMap]


def parse_yaml(text: str, source: str) -> YNode | None:
    """Compose ``text`` and convert it to line-aware nodes (None for an empty file).

    YAML syntax errors, unsupported tags, repeated keys and recursive aliases raise
    :class:`ModelError` with the line PyYAML reports.
    """
    try:
        loader = ModelLoader(text)      # the reader checks characters here
        node = loader.get_single_node()
    except yaml.YAMLError as exc:
        raise _syntax_error(exc, text, source) from None
    try:
        if node is None:
            return None
        return _Walker(loader, text, source).convert(node, "")
    finally:
        loader.dispose()


def _line_text(text: str, line: int | None) -> str:
    lines = text.splitlines()
    if line is None or not 1 <= line <= len(lines):
        return ""
    return lines[line - 1].strip()


def _syntax_error(exc: yaml.YAMLError, text: str, source: str) -> ModelError:
    """Turn a PyYAML error into a ModelError at the line PyYAML reports."""
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    if mark is not None:
        line = mark.line + 1
    elif isinstance(exc, yaml.reader.ReaderError):
        line = text.count("\n", 0, exc.position) + 1
    else:
        line = None
    if isinstance(exc, yaml.MarkedYAMLError):
        words = [w for w in (exc.problem, exc.context) if w]
        rule = "; ".join(words) if words else "is not valid YAML"
    elif isinstance(exc, yaml.reader.ReaderError):
        char = exc.character if isinstance(exc.character, int) else ord(exc.character)
        rule = f"unacceptable character #x{char:04x}"
    else:
        rule = str(exc).splitlines()[0]
    return ModelError(source, line, "YAML", f"is not valid YAML: {rule}",
                      _line_text(text, line))


class _Walker:
    """Converts a composed node tree, once per node (aliases share the result)."""

    def __init__(self, loader: ModelLoader, text: str, source: str):
        self.loader = loader
        self.text = text
        self.source = source
        self.done: dict[int, YNode] = {}
        self.active: set[int] = set()

    def convert(self, node: yaml.Node, item: str) -> YNode:
        key = id(node)
        if key in self.done:
            return self.done[key]
        line = node.start_mark.line + 1
        if key in self.active:
            raise ModelError(self.source, line, item or "YAML",
                             "is a recursive alias (it contains itself)", show_value=False)
        self.active.add(key)
        try:
            if isinstance(node, yaml.MappingNode):
                result = self.mapping(node, item, line)
            elif isinstance(node, yaml.SequenceNode):
                self.check_tag(node, SEQ_TAG, item, line)
                result = YSeq(tuple(self.convert(n, f"{item}[{k}]")
                                    for k, n in enumerate(node.value)), line)
            else:
                result = self.scalar(node, item, line)
        finally:
            self.active.discard(key)
        self.done[key] = result
        return result

    def check_tag(self, node, tag: str, item: str, line: int):
        if node.tag != tag:
            raise ModelError(self.source, line, item or "YAML",
                             "has an unsupported YAML tag", node.tag)

    def scalar(self, node: yaml.ScalarNode, item: str, line: int) -> YScalar:
        if node.tag not in SCALAR_TAGS:
            raise ModelError(self.source, line, item or "YAML",
                             "has an unsupported YAML tag", node.tag)
        try:
            value = self.loader.construct_object(node, deep=True)
        except Exception:     # noqa: BLE001 - PyYAML's scalar constructors raise
            # ValueError, KeyError, AttributeError, ... for text that does not fit an
            # explicit tag (``!!int abc``, ``!!bool maybe``).
            raise ModelError(self.source, line, item or "YAML",
                             f"cannot be read as {node.tag}", node.value) from None
        return YScalar(value, node.value, line)

    def mapping(self, node: yaml.MappingNode, item: str, line: int) -> YMap:
        self.check_tag(node, MAP_TAG, item, line)
        entries: dict[str, YNode] = {}
        key_lines: dict[str, int] = {}
        for key_node, value_node in node.value:
            key_line = key_node.start_mark.line + 1
            if not isinstance(key_node, yaml.ScalarNode):
                raise ModelError(self.source, key_line, item or "YAML",
                                 "has a key that is not a plain name",
                                 _line_text(self.text, key_line))
            key = key_node.value
            path = f"{item}.{key}" if item else key
            if key in entries:
                raise ModelError(self.source, key_line, path,
                                 f"duplicate key (first given on line {key_lines[key]})",
                                 key)
            key_lines[key] = key_line
            entries[key] = self.convert(value_node, path)
        return YMap(entries, key_lines, line)

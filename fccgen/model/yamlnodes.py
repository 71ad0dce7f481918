"""YAML text -> plain values that remember their line.

The model loader needs the line of every value to say where a rule is broken, and it
must reject what PyYAML silently accepts (a repeated key keeps only its last value).
So the text is *composed* into PyYAML's node tree with a safe loader
(:mod:`fccgen.model.yamlcompose`), and that tree is walked here into three small node
types:

* :class:`YScalar` -- a scalar: its safely constructed value and its source text;
* :class:`YSeq`    -- a sequence of nodes;
* :class:`YMap`    -- a mapping from key text to node, with the line of every key.

Lines are 1-based. Scalars are built only by :class:`yaml.SafeLoader`'s constructors;
nothing from the file reaches ``eval`` or an arbitrary Python constructor.

Limits (docs/reliability.md, "Input"): a text of at most MAX_INPUT_CHARS characters,
nested at most MAX_DEPTH levels, and at most MAX_NODES nodes, also once every alias is
expanded. Each is refused before it costs much: the depth and the node count while
the tree is composed, the expanded size while it is walked bottom-up here, where an
alias is a shared node whose size is already known, so a "billion laughs" file is
refused after walking its few distinct nodes and never expanded.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import yaml

from ..errors import ModelError, clip
from . import yamlcompose
from .yamlcompose import MAX_DEPTH, MAX_INPUT_CHARS, MAX_NODES, NestingError, compose

__all__ = ["MAX_DEPTH", "MAX_INPUT_CHARS", "MAX_NODES", "YMap", "YNode", "YScalar", "YSeq",
           "parse_yaml", "shown"]

# Values of at most this many nodes are shown whole in a message; larger ones as the
# start of their text (ModelError clips every value to SHOWN_VALUE_CHARS anyway).
SHOW_NODES = 64
SHOWN_START = 150
# A key longer than this is cut in the item paths of its children.
PATH_KEY_CHARS = 100

MAP_TAG = "tag:yaml.org,2002:map"
# Scalar tags the safe loader builds (explicit or resolved); any other tag is refused.
SCALAR_TAGS = frozenset(f"tag:yaml.org,2002:{t}" for t in
                        ("null", "bool", "int", "float", "str", "timestamp", "binary"))
SEQ_TAG = "tag:yaml.org,2002:seq"


@dataclass(frozen=True, eq=False)
class YScalar:
    value: object          # str, int, float, bool, None (or another safe YAML scalar)
    text: str              # the scalar as written (without quotes)
    line: int
    size = 1               # nodes, aliases expanded

    def plain(self):
        return self.value


@dataclass(frozen=True, eq=False)
class YSeq:
    items: tuple["YNode", ...]
    line: int
    size: int = 1          # nodes, aliases expanded (set by the walker)

    def plain(self):
        return [n.plain() for n in self.items]


@dataclass(frozen=True, eq=False)
class YMap:
    entries: dict[str, "YNode"]     # key text -> value node, in file order
    key_lines: dict[str, int]       # key text -> line of the key
    line: int
    size: int = 1                   # nodes, aliases expanded (set by the walker)

    def plain(self):
        return {k: n.plain() for k, n in self.entries.items()}


class Clipped(str):
    """The start of a large value's text; shown as is (no quotes) in a message."""

    def __repr__(self) -> str:
        return str(self)


def shown(node: "YNode"):
    """The value of ``node`` for a message: plain data when small, else the start of
    its text in flow style and its size, written without expanding more than
    SHOWN_START characters."""
    if node.size <= SHOW_NODES:
        return node.plain()
    out: list[str] = []
    _preview(node, out, SHOWN_START + 1)
    return Clipped("".join(out)[:SHOWN_START] + f"... ({node.size} nodes)")


def _preview(node: "YNode", out: list[str], budget: int) -> int:
    """Append flow-style text of ``node`` to ``out`` until ``budget`` characters."""
    if budget <= 0:
        return 0
    if isinstance(node, YScalar):
        value = node.value
        text = repr(value[:budget]) if isinstance(value, str) else node.text[:budget]
        out.append(text[:budget])
        return budget - len(out[-1])
    pairs = (node.entries.items() if isinstance(node, YMap)
             else ((None, n) for n in node.items))
    out.append("{" if isinstance(node, YMap) else "[")
    budget -= 1
    for k, (key, child) in enumerate(pairs):
        if budget <= 0:
            break
        out.append((", " if k else "") + ("" if key is None else f"{key[:budget]}: "))
        out[-1] = out[-1][:budget]
        budget = _preview(child, out, budget - len(out[-1]))
    out.append("}" if isinstance(node, YMap) else "]")
    return budget - 1


YNode = Union[YScalar, YSeq, YMap]


def parse_yaml(text: str, source: str) -> YNode | None:
    """Compose ``text`` and convert it to line-aware nodes (None for an empty file).

    YAML syntax errors, unsupported tags, repeated keys and recursive aliases raise
    :class:`ModelError` with the line PyYAML reports.
    """
    if len(text) > MAX_INPUT_CHARS:
        raise ModelError(source, None, "model file",
                         f"is {len(text)} characters long; at most {MAX_INPUT_CHARS} "
                         "are read", show_value=False)
    try:
        loader, node = compose(text)
    except NestingError as exc:
        line = exc.problem_mark.line + 1
        raise ModelError(source, line, "YAML", exc.problem,
                         _line_text(text, line)) from None
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


def _path(item: str, key) -> str:
    """Item path of a child, with a long key cut (the path is built for every node)."""
    if isinstance(key, int):
        return f"{item}[{key}]"
    key = clip(key, PATH_KEY_CHARS)
    return f"{item}.{key}" if item else key


class _Walker:
    """Converts a composed node tree, once per node (aliases share the result)."""

    def __init__(self, loader, text: str, source: str):
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
                items = tuple(self.convert(n, _path(item, k))
                              for k, n in enumerate(node.value))
                result = YSeq(items, line, self.size(items, item, line))
            else:
                result = self.scalar(node, item, line)
        finally:
            self.active.discard(key)
        self.done[key] = result
        return result

    def size(self, children, item: str, line: int) -> int:
        """1 + the expanded sizes of ``children``; refused above MAX_NODES."""
        total = 1 + sum(c.size for c in children)
        limit = yamlcompose.MAX_NODES
        if total > limit:
            raise ModelError(self.source, line, item or "YAML",
                             f"expands to more than {limit} YAML nodes (aliases "
                             "counted as the nodes they repeat); a model needs far fewer",
                             total)
        return total

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
            path = _path(item, key)
            if key in entries:
                raise ModelError(self.source, key_line, path,
                                 f"duplicate key (first given on line {key_lines[key]})",
                                 key)
            key_lines[key] = key_line
            entries[key] = self.convert(value_node, path)
        return YMap(entries, key_lines, line, self.size(entries.values(), item, line))

"""YAML text -> PyYAML's node tree, within limits.

Two loaders compose the same tree with the same safe constructors and resolvers:

* :class:`FastModelLoader` takes its events from libyaml's C parser (when PyYAML was
  built with it) and composes them with PyYAML's Python composer: ~7x faster than
  the Python parser (four_bar.yaml: 1.1 ms instead of 7.2 ms), and the composer stays
  the one whose depth and node count are bounded here (libyaml's own composer
  recurses in C);
* :class:`ModelLoader` is PyYAML's Python loader. It reads every text the C parser
  refuses, so a syntax error is worded and placed as PyYAML words it, whichever
  parser is present.

Both refuse nesting deeper than MAX_DEPTH and more than MAX_NODES composed nodes
before they cost much (PyYAML's composer recurses and raised RecursionError near 490
levels); the Python scanner also refuses deep flow collections at once, as it reads
up to 1 kB ahead and checks every open level at each token (seconds for deep
``[[[[...``).
"""
from __future__ import annotations

import re

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.resolver import Resolver

# The largest example (A02, 40 four-bars) is 15 kB of 1,729 nodes nested 6 levels deep.
# The limits are ~60x, ~60x and ~8x that, and keep a file's cost to seconds: PyYAML's
# pure-Python parser and composer take ~45 us and ~1 kB per node (measured: 500,000
# nodes, 23 s and 460 MB), so MAX_NODES composed nodes cost ~5 s and ~100 MB at worst.
MAX_INPUT_CHARS = 1_000_000
MAX_DEPTH = 50
MAX_NODES = 100_000

# YAML 1.2 floats with an exponent (1e-3, 5E+2, 2.5e3): PyYAML's YAML 1.1 resolver
# wants a dot and a signed exponent, and reads these as strings otherwise.
FLOAT_12 = re.compile(r"^[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)[eE][-+]?[0-9]+$")
FLOAT_TAG = "tag:yaml.org,2002:float"

TOO_DEEP = f"nests deeper than {MAX_DEPTH} levels (a model needs fewer than 10)"


class NestingError(yaml.MarkedYAMLError):
    """The text nests collections deeper than MAX_DEPTH or has more than MAX_NODES
    nodes."""


class _Bounded:
    """Composer limits: depth and number of composed nodes."""

    depth = 0
    composed = 0

    def compose_node(self, parent, index):
        if self.depth >= MAX_DEPTH:
            raise NestingError(None, None, TOO_DEEP, self.peek_event().start_mark)
        self.composed += 1
        if self.composed > MAX_NODES:
            raise NestingError(None, None, f"has more than {MAX_NODES} YAML nodes (a "
                               "model needs far fewer)", self.peek_event().start_mark)
        self.depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1


class ModelLoader(_Bounded, yaml.SafeLoader):
    """PyYAML's Python safe loader, bounded, reading YAML 1.2 exponent floats."""

    def fetch_flow_collection_start(self, TokenClass):
        if self.flow_level >= MAX_DEPTH:
            raise NestingError(None, None, TOO_DEEP, self.get_mark())
        super().fetch_flow_collection_start(TokenClass)


ModelLoader.add_implicit_resolver(FLOAT_TAG, FLOAT_12, list("-+0123456789."))

try:
    from yaml._yaml import CParser
except ImportError:             # PyYAML built without libyaml
    CParser = None

if CParser is None:
    FastModelLoader = None
else:
    class FastModelLoader(_Bounded, CParser, Composer, SafeConstructor, Resolver):
        """libyaml's events, PyYAML's Python composer (bounded), safe constructors."""

        # The C parser's own get_single_node composes in C, unbounded: use Python's.
        get_single_node = Composer.get_single_node
        compose_document = Composer.compose_document

        def __init__(self, stream):
            CParser.__init__(self, stream)
            Composer.__init__(self)
            SafeConstructor.__init__(self)
            Resolver.__init__(self)

    FastModelLoader.add_implicit_resolver(FLOAT_TAG, FLOAT_12, list("-+0123456789."))


def compose(text: str):
    """``(loader, root node or None)`` of ``text``; the caller disposes of the loader
    once it has constructed the scalars it needs. Raises yaml.YAMLError (NestingError
    past the limits) as PyYAML's Python loader raises it."""
    if FastModelLoader is not None:
        loader = FastModelLoader(text)
        try:
            return loader, loader.get_single_node()
        except NestingError:
            loader.dispose()
            raise
        except yaml.YAMLError:
            loader.dispose()        # read again below, for PyYAML's wording and line
    loader = ModelLoader(text)
    return loader, loader.get_single_node()

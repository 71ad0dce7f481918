"""Reading the ``tables:`` section of a model file (docs/model-file.md "tables",
docs/flexible.md "Tape-spring hinges"): named functions of one argument, given by a
CSV file of (argument, value) rows, that load expressions call by name.

    tables:
      hinge_moment: {file: hinge_moment.csv}     # columns: angle (rad), moment (N m)

The file is read here, once, by :func:`fccgen.expressions.tables.read_table` (a
regular file under the model file's folder or a folder of ``FCCGEN_TABLE_DIRS``; at
least 2 rows, finite numbers, the first column strictly increasing): a bad table is
reported with the model file's line, the item ``tables.<name>.file``, the CSV row and
the rule. The name must not be a function or constant of the expression grammar, nor
``t``, nor any other name of the model.
"""
from __future__ import annotations

import numpy as np

from .fields import Reader, child
from .yamlnodes import YNode

TABLE_KEYS = ("file",)


class TableReader(Reader):
    """Reads the tables; ``claim`` reserves each table's name among the model's."""

    def __init__(self, source: str, claim):
        super().__init__(source)
        self.claim = claim

    def tables(self, node: YNode) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        from ..expressions.grammar import RESERVED
        from ..expressions.tables import read_table
        out = {}
        for name, line, value, item in self.entries(node, "tables"):
            if name in RESERVED or name == "t":
                raise self.fail(line, item, "is a name of the expression grammar (a "
                                "function, a constant or the time t); name the table "
                                "otherwise", name)
            self.claim(name, "table", line, item)
            m = self.mapping(value, item, TABLE_KEYS)
            entry = m.entries["file"]
            path = self.text(entry, child(item, "file"))
            out[name] = read_table(path, source=self.source, line=entry.line,
                                   item=child(item, "file"), columns=("x", "value"))
        return out

"""A model file cannot run code: text that would close the comment the generated C
puts an expression in, and compile what follows into the module, is refused.

The payload of each case is a C constructor function that, were it compiled into the
model's module, would create a marker file when the module is loaded. The model must
be refused when it is read (a ModelError naming file, line, item and rule), nothing is
built, and the marker never appears.
"""
from __future__ import annotations

from pathlib import Path

import pytest

import fccgen
from fccgen.errors import ModelError

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def payload(marker: Path) -> str:
    """An expression that closes the C block comment it is pasted into, defines a
    constructor that creates ``marker``, and opens a comment again."""
    return ('0.1*t # */ __attribute__((constructor)) static void fcc_pwn(void) '
            '{ extern int system(const char *); system(\\"touch ' + str(marker)
            + '\\"); } /*')


def attacked_model(tmp_path: Path, where: str) -> tuple[Path, Path]:
    marker = tmp_path / "PWNED"
    text = (EXAMPLES / "four_bar_driven.yaml").read_text()
    attack = payload(marker)
    if where == "driver":
        text = text.replace('angle: "10*t"', f'angle: "{attack}"')
    else:
        text += f'loads:\n  - {{type: torque, body: crank, value: [0, 0, "{attack}"]}}\n'
    path = tmp_path / "attack.yaml"
    path.write_text(text)
    return path, marker


@pytest.mark.parametrize("where, item", [("driver", "drivers[0].angle"),
                                         ("load", "loads[0].value[2]")])
def test_comment_in_an_expression_cannot_inject_code(tmp_path, where, item):
    path, marker = attacked_model(tmp_path, where)
    build = tmp_path / "generated"
    with pytest.raises(ModelError) as err:
        fccgen.load(path, build)
    assert err.value.item == item
    assert err.value.file == str(path) and err.value.line is not None
    assert "comment" in err.value.rule
    assert not marker.exists()
    assert not build.exists() or not any(build.rglob("*.c"))

"""The model-writing scripts (examples/make_*.py) answer --help with their docstring and
refuse a size that is not a positive whole number with a usage line, not a traceback."""
from __future__ import annotations

import pytest

from conftest import example_module

SCRIPTS = {"make_n_four_bar": False, "make_panel_array": True,
           "make_pendulum_on_cart": False, "make_scissor_boom": True,
           "make_scissor_mast": True}          # True: main takes the program name first


def call(name, *args):
    argv = ["prog", *args] if SCRIPTS[name] else list(args)
    return example_module(name).main(argv)


@pytest.mark.parametrize("name", SCRIPTS)
def test_help_is_the_scripts_docstring(name, capsys):
    with pytest.raises(SystemExit) as stop:
        call(name, "--help")
    assert stop.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage:") and example_module(name).__doc__.splitlines()[0] in out


@pytest.mark.parametrize("name", SCRIPTS)
@pytest.mark.parametrize("size, says", [("0", "must be at least 1, not 0"),
                                        ("three", "invalid int value: 'three'")])
def test_a_bad_size_is_refused_with_a_usage_line(name, size, says, capsys):
    with pytest.raises(SystemExit) as stop:
        call(name, size)
    assert stop.value.code == 2
    assert says in capsys.readouterr().err


@pytest.mark.parametrize("name", SCRIPTS)
def test_a_size_and_a_path_write_that_file(name, tmp_path):
    path = tmp_path / "model.yaml"
    assert call(name, "2", str(path)) == 0
    assert path.read_text().startswith("#")

"""Every public function, class and method of the package has a numpydoc docstring that
documents its parameters and return value and renders as valid reStructuredText (the rules:
``tests/docstring_check.py``); the checker itself catches what it should."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from docstring_check import check_file, check_function, public_modules  # noqa: E402


@pytest.mark.parametrize("path", public_modules(), ids=lambda p: p.stem if p.stem !=
                         "__init__" else p.parent.name)
def test_public_api_has_numpydoc_docstrings(path):
    problems = check_file(path)
    assert not problems, "\n".join(problems)


def _problems(src: str) -> list[str]:
    fn = ast.parse(src).body[0]
    out: list[str] = []
    check_function(fn, "f", out)
    return out


def test_the_checker_finds_what_is_missing():
    assert _problems("def f(a):\n    return a\n") == ["f: no docstring"]
    missing = _problems('def f(a, b):\n    """Sum.\n\n    Parameters\n    ----------\n'
                        '    a : float\n        m.\n    """\n    return a + b\n')
    assert any("not documented: b" in p for p in missing)
    assert any("no Returns section" in p for p in missing)
    extra = _problems('def f():\n    """Nothing.\n\n    Parameters\n    ----------\n'
                      '    c : int\n        count.\n    """\n')
    assert any("does not take: c" in p for p in extra)
    bad_rst = _problems('def f():\n    """Use ``x to y."""\n')
    assert any("reStructuredText" in p for p in bad_rst)
    good = _problems('def f(a):\n    """Double a length.\n\n    Parameters\n    ----------\n'
                     '    a : float\n        Length, m.\n\n    Returns\n    -------\n'
                     '    float\n        ``2 a``, m.\n    """\n    return 2 * a\n')
    assert good == []

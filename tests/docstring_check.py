"""The numpydoc docstring check of the public API (``tests/test_docstrings.py``).

Public: every module of ``src/oneocean`` whose name does not start with ``_``; in it, every
top-level function and class whose name does not start with ``_``, and every method of such a
class whose name does not start with ``_`` (``__init__`` included: its parameters belong to
the class). Each must have a docstring that numpydoc parses, with a one-line summary; every
parameter named in its signature (but ``self``/``cls`` and ``*args``/``**kwargs``-style
catch-alls, the parameters of a task's or a policy's hook, documented once in
:mod:`oneocean.tasks.loop` and :mod:`oneocean.tasks.public`, and of a task's ``reset`` and
``make``, documented once in :mod:`oneocean.tasks`: :data:`CONTRACTS`, and the names
of a module's ``VOCABULARY`` dict, which documents them once for all its functions) described
under ``Parameters`` (the class docstring may describe ``__init__``'s
parameters, and a dataclass/NamedTuple's fields under ``Attributes`` or ``Parameters``); no
parameter described that the signature lacks; a ``Returns`` (or ``Yields``) section where the
function returns a value; and the docstring, as numpydoc hands it to Sphinx, is valid
reStructuredText (no docutils warning: the docs site builds with ``-W``). Read from the source
(AST), so numba kernels count like Python functions.

Run on files to see what is missing::

    python tests/docstring_check.py src/oneocean/reporting/tables.py
"""
from __future__ import annotations

import ast
import sys
import warnings
from pathlib import Path

from numpydoc.docscrape import NumpyDocString
from numpydoc.docscrape_sphinx import SphinxDocString

SRC = Path(__file__).resolve().parents[1] / "src" / "oneocean"


def public_modules(root: Path = SRC) -> list[Path]:
    """The public modules' files under ``root`` (no path part starts with ``_`` but
    ``__init__.py``)."""
    out = []
    for p in sorted(root.rglob("*.py")):
        parts = p.relative_to(root).parts
        if any(x.startswith("_") and x != "__init__.py" for x in parts):
            continue
        out.append(p)
    return out


def _returns_value(fn: ast.AST) -> bool:
    """Whether ``fn``'s own body (not nested functions) returns a value or yields."""
    stack = list(ast.iter_child_nodes(fn))
    while stack:
        n = stack.pop()
        if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue
        if isinstance(n, ast.Return) and n.value is not None and not (
                isinstance(n.value, ast.Constant) and n.value.value is None):
            return True
        if isinstance(n, (ast.Yield, ast.YieldFrom)):
            return True
        stack.extend(ast.iter_child_nodes(n))
    return False


#: Signatures whose parameters are documented once, in the contract of the episode loop
#: (``oneocean.tasks.loop``: the env hooks and the policy hooks on their context) and of the
#: public view (``oneocean.tasks.public``: a task's ``brief``, ``team_obs`` and ``report``; a
#: policy's ``params``, ``memory`` and ``prepare``) and of a task's scenario (``oneocean.tasks``:
#: ``reset`` and ``make``): a hook's docstring says what it does, not its arguments again.
CONTRACTS = {
    ("C", "e", "k"), ("C", "e", "k", "i"),
    ("ctx", "e"), ("ctx", "e", "k"), ("ctx", "e", "k", "i"),
    ("P", "W", "init", "m"), ("W",), ("method", "B"), ("B", "M"), ("B", "M", "H"),
    ("grid", "tier", "n_agents", "n_episodes", "seed"), ("grid", "tier", "init"),
}


def _arg_names(fn) -> list[str]:
    a = fn.args
    names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
    return [n for n in names if n not in ("self", "cls")]


def _is_property(fn) -> bool:
    return any((isinstance(d, ast.Name) and d.id in ("property", "cached_property"))
               or (isinstance(d, ast.Attribute) and d.attr in ("setter", "cached_property"))
               for d in fn.decorator_list)


def _documented(doc: NumpyDocString, *sections: str) -> set[str]:
    names = set()
    for sec in sections:
        for p in doc[sec]:
            for n in p.name.split(","):
                names.add(n.strip().lstrip("*"))
    return names


def _parse(text: str, where: str, problems: list[str]):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            return NumpyDocString(text)
        except Exception as exc:  # noqa: BLE001 - any parse failure is a finding
            problems.append(f"{where}: docstring does not parse as numpydoc ({exc})")
            return None


_SPHINX_ROLES = ("func", "class", "meth", "mod", "attr", "data", "obj", "exc", "ref", "doc",
                 "term", "py:func", "py:class", "py:meth", "py:mod", "py:attr", "py:data",
                 "py:obj", "py:exc", "envvar", "file", "samp", "command", "program", "option",
                 "kbd", "abbr", "download", "any", "numref", "eq", "cite")
_SPHINX_DIRECTIVES = ("versionadded", "versionchanged", "deprecated", "seealso",
                      "autosummary", "plot", "currentmodule", "code-block", "testcode")
_rst_ready = False


def _rst_setup() -> None:
    global _rst_ready
    if _rst_ready:
        return
    from docutils import nodes
    from docutils.parsers.rst import Directive, directives, roles

    def role(name, rawtext, text, lineno, inliner, options=None, content=None):
        return [nodes.literal(rawtext, text)], []

    for r in _SPHINX_ROLES:
        roles.register_local_role(r, role)

    class Passthrough(Directive):
        has_content = True
        optional_arguments = 10
        final_argument_whitespace = True
        option_spec = None

        def run(self):
            return []

    Passthrough.option_spec = {k: directives.unchanged for k in
                               ("noindex", "toctree", "nosignatures", "language",
                                "linenos", "caption")}
    for d in _SPHINX_DIRECTIVES:
        directives.register_directive(d, Passthrough)
    _rst_ready = True


def rst_problems(text: str) -> list[str]:
    """docutils' warnings on ``text`` (a docstring) as numpydoc renders it for Sphinx."""
    import io

    from docutils.core import publish_doctree

    _rst_setup()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rst = str(SphinxDocString(text))
    stream = io.StringIO()
    publish_doctree(rst, settings_overrides={"warning_stream": stream, "report_level": 2,
                                             "halt_level": 5})
    return [ln.split("(WARNING/2)")[-1].split("(ERROR/3)")[-1].strip()
            for ln in stream.getvalue().splitlines()
            if "WARNING/" in ln or "ERROR/" in ln or "SEVERE/" in ln]


def vocabulary(tree: ast.Module) -> set[str]:
    """The keys of a module's ``VOCABULARY = {...}`` (names documented once for every function
    of the module), or an empty set."""
    for node in tree.body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and isinstance(node.targets[0], ast.Name) and node.targets[0].id == "VOCABULARY"
                and isinstance(node.value, ast.Dict)):
            return {k.value for k in node.value.keys if isinstance(k, ast.Constant)}
    return set()


def check_function(fn, where: str, problems: list[str], class_doc=None,
                   known: set[str] = frozenset()) -> None:
    """Append ``fn``'s docstring problems to ``problems`` (``known``: names documented
    once for the module, its ``VOCABULARY``)."""
    text = ast.get_docstring(fn)
    if fn.name == "__init__" and not text:
        text = None
    if not text and fn.name != "__init__":
        problems.append(f"{where}: no docstring")
        return
    doc = _parse(text, where, problems) if text else None
    if text and doc is None:
        return
    if text:
        for w in rst_problems(text):
            problems.append(f"{where}: reStructuredText: {w}")
    if doc is not None and fn.name != "__init__" and not "".join(doc["Summary"]).strip():
        problems.append(f"{where}: no one-line summary")
    if _is_property(fn):
        return
    args = _arg_names(fn)
    have = set(args) if tuple(args) in CONTRACTS else set(known)
    if doc is not None:
        have |= _documented(doc, "Parameters", "Other Parameters")
    if fn.name == "__init__" and class_doc is not None:
        have |= _documented(class_doc, "Parameters", "Other Parameters", "Attributes")
    missing = [a for a in args if a not in have]
    if missing:
        problems.append(f"{where}: parameters not documented: {', '.join(missing)}")
    extra = sorted(n for n in (_documented(doc, "Parameters") if doc else set())
                   if n not in args and n not in ("args", "kwargs", "kw", "**kw")
                   and fn.args.vararg is None and fn.args.kwarg is None)
    if extra:
        problems.append(f"{where}: documents parameters it does not take: {', '.join(extra)}")
    if (fn.name != "__init__" and _returns_value(fn) and doc is not None
            and not (doc["Returns"] or doc["Yields"])):
        problems.append(f"{where}: returns a value but has no Returns section")


def check_file(path: Path) -> list[str]:
    """Every docstring problem of the public objects in ``path``."""
    rel = path.relative_to(SRC.parent) if path.is_relative_to(SRC.parent) else path
    tree = ast.parse(path.read_text())
    known = vocabulary(tree)
    problems: list[str] = []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            if not node.name.startswith("_"):
                check_function(node, f"{rel}:{node.lineno} {node.name}", problems,
                               known=known)
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            where = f"{rel}:{node.lineno} {node.name}"
            text = ast.get_docstring(node)
            if not text:
                problems.append(f"{where}: no docstring")
                class_doc = None
            else:
                class_doc = _parse(text, where, problems)
                for w in rst_problems(text):
                    problems.append(f"{where}: reStructuredText: {w}")
            for m in node.body:
                if isinstance(m, (ast.FunctionDef, ast.AsyncFunctionDef)) and (
                        not m.name.startswith("_") or m.name == "__init__"):
                    check_function(m, f"{where}.{m.name}", problems, class_doc)
    return problems


def main(argv: list[str]) -> int:
    files = [Path(a).resolve() for a in argv] or public_modules()
    n = 0
    for f in files:
        for line in check_file(f):
            print(line)
            n += 1
    print(f"{n} problems in {len(files)} files", file=sys.stderr)
    return 1 if n else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

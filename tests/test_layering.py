"""Who may import whom: the world never depends on the agents.

The engine, the sensor models and the physical models import neither tasks nor methods; a
task module (scenario, hooks, judge, accounting) imports no method; a method reads the
task's public view. The two meet only in ``oneocean.kernels`` (each task's compiled loop)
and in the drivers that look a kernel up by name.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import oneocean
from oneocean.errors import ConfigError

PKG = Path(oneocean.__file__).resolve().parent


def _imports(path: Path) -> set[str]:
    """Absolute names of every module ``path`` imports (top level and inside functions)."""
    parts = path.relative_to(PKG.parent).with_suffix("").parts
    package = parts[:-1] if parts[-1] != "__init__" else parts[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = list(package[:len(package) - node.level + 1]) if node.level else []
            mod = ".".join(base + ([node.module] if node.module else []))
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names)
    return out


def _offenders(folder: str, forbidden: tuple[str, ...]) -> dict[str, list[str]]:
    bad = {}
    for f in sorted((PKG / folder).rglob("*.py")):
        hits = sorted(m for m in _imports(f) if m.startswith(forbidden))
        if hits:
            bad[f.relative_to(PKG).as_posix()] = hits
    return bad


def test_the_import_reader_sees_relative_imports():
    names = _imports(PKG / "kernels" / "g2g.py")
    assert "oneocean.methods.heuristic.g2g" in names and "oneocean.tasks.g2g" in names


@pytest.mark.parametrize("folder", ["engine", "sensing", "models"])
def test_the_world_imports_no_task_and_no_method(folder):
    assert _offenders(folder, ("oneocean.tasks", "oneocean.methods", "oneocean.kernels")) == {}


#: The core backend's driver looks a task's compiled loop up by name (the task's spec); it is
#: the one file of the task layer that reaches the kernels (and through them the policies).
DRIVERS = {"tasks/episodes.py": ["oneocean.kernels", "oneocean.kernels.kernel_module"]}


def test_tasks_import_no_method():
    assert _offenders("tasks", ("oneocean.methods", "oneocean.kernels")) == DRIVERS


def test_every_builtin_task_binds_its_policy_in_its_kernel_module():
    from oneocean.kernels import kernel_module
    from oneocean.registry import builtin_task_ids, task_spec

    for task in builtin_task_ids():
        spec = task_spec(task)
        kern = kernel_module(task)
        assert kern.__name__ == spec.kernel == f"oneocean.kernels.{spec.module.split('.')[-1]}"
        assert kern.TASK.__name__ == spec.module
        assert kern.POLICY.__name__ == f"oneocean.methods.heuristic.{spec.module.split('.')[-1]}"


def test_ft_cue_lead_is_the_inverse_of_the_tracking_gain():
    from oneocean.methods.heuristic import ft as policy
    from oneocean.tasks import ft

    assert ft.CUE_LEAD_S == pytest.approx(10.0 / 3.0)
    assert policy.KP == 0.3 and policy.KP * ft.CUE_LEAD_S == pytest.approx(1.0)


#: What a policy module may not name: the task's params and work arrays, the grid (the
#: truth), the loop's params and state, the true states (docs/policy.md). A policy reads its
#: context ``C`` (briefing, observation, team observation, its params and memory, report).
HIDDEN = {"grid", "P", "W", "LS", "LP", "state"}


def _policy_functions(path: Path):
    tree = ast.parse(path.read_text())
    return [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)]


@pytest.mark.parametrize("path", sorted((PKG / "methods" / "heuristic").glob("[!_]*.py")),
                         ids=lambda p: p.stem)
def test_a_policy_reads_only_the_public_view(path):
    """Every built-in heuristic is a policy of the briefing and the observation: its hooks
    take the context ``(C, e, k[, i])``, its Python functions the briefing, its params and its
    memory, and no function names the task's params, work arrays, the grid, the loop's state
    or the true states (the parity test, tests/test_parity.py, shows it decides the same
    through the step API)."""
    funcs = {f.name: f for f in _policy_functions(path)}
    args = {name: [a.arg for a in f.args.args] for name, f in funcs.items()}
    assert args["act"] == ["C", "e", "k", "i"]
    assert "plan" not in args or args["plan"] == ["C", "e", "k"]
    assert args["params"] == ["method", "B"] and args["memory"][:2] == ["B", "M"]
    if "prepare" in args:
        assert args["prepare"] == ["B", "M", "H"]
    bad = []
    for f in funcs.values():
        for node in ast.walk(f):
            if isinstance(node, ast.Name) and node.id in HIDDEN:
                bad.append(f"{f.name}: {node.id}")
            elif isinstance(node, ast.arg) and node.arg in HIDDEN:
                bad.append(f"{f.name}: argument {node.arg}")
    assert bad == []


def test_the_layering_check_catches_a_policy_that_reads_the_work_arrays(tmp_path):
    src = tmp_path / "leaky.py"
    src.write_text("def act(C, e, k, i):\n    return W.goal[e, 0], 0.0, 0.0, 0.0\n")
    names = {n.id for f in _policy_functions(src) for n in ast.walk(f)
             if isinstance(n, ast.Name)}
    assert names & HIDDEN == {"W"}

"""Which source files a workflow job's results depend on, and their hash (a rule's ``code``
param: editing one of them reruns the job, editing anything else does not).

A rollout cell of task ``T`` depends on the engine, the physical models, the sensor models and
their table, the one episode loop and its driver, the task layer's shared modules
(``tasks/common.py``, ``tiers.py``, ``regime.py``, ``spawn.py``, ``waypoints.py``), the
methods' steering laws (``methods/steering.py``), the learned controller the loop links
(``tasks/learned.py``), the route planner (``tasks/routing.py``), ``T``'s own task module,
heuristic and kernel module, ``T``'s tier table and the vehicle table -- not on the other
tasks' modules or tables, so editing one task reruns only its cells.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
from pathlib import Path

_PKG = Path(__file__).resolve().parents[1]

#: Files and folders every rollout cell depends on (relative to the package).
ROLLOUT_SHARED = ("engine", "models", "methods/heuristic/__init__.py", "methods/steering.py",
                  "kernels/__init__.py", "sensing", "tasks/__init__.py", "tasks/common.py",
                  "tasks/tiers.py", "tasks/regime.py", "tasks/spawn.py", "tasks/waypoints.py",
                  "tasks/loop.py", "tasks/episodes.py", "tasks/learned.py", "tasks/routing.py",
                  "data/vehicles.yaml", "data/sensors.yaml", "errors.py")


def _files(entry: Path) -> list[Path]:
    if entry.is_dir():
        return sorted(f for pat in ("*.py", "*.yaml") for f in entry.rglob(pat))
    return [entry]


def module_file(module: str) -> Path:
    """The source file of a dotted module name (the module itself is not imported).

    Parameters
    ----------
    module : str
        A dotted module name, e.g. ``"oneocean.tasks.g2g"``.

    Returns
    -------
    pathlib.Path
        The resolved source file.

    Raises
    ------
    FileNotFoundError
        No such module, or it has no source file.
    """
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        raise FileNotFoundError(f"code version: module {module} not found")
    return Path(spec.origin).resolve()


#: Task modules that import another task's module (and its heuristic twin): RF's transit
#: reuses G2G's band draw, power and energy accounting.
TASK_DEPENDS = {"RF": ("G2G",)}


def task_files(task: str) -> list[Path]:
    """The files a rollout cell of ``task`` depends on.

    These are :data:`ROLLOUT_SHARED` plus the task's module, its heuristic twin
    ``methods/heuristic/<module>.py`` and its kernel module
    (:attr:`~oneocean.registry.TaskSpec.kernel_module`), and its tier table; and those of
    the tasks it imports, :data:`TASK_DEPENDS`.

    Parameters
    ----------
    task : str
        A registered task id, e.g. ``"G2G"``.

    Returns
    -------
    list of pathlib.Path
        The resolved files, sorted, without duplicates.
    """
    from ..registry import task_spec

    spec = task_spec(task)
    mod = module_file(spec.module)
    own = [mod, module_file(spec.kernel_module), Path(spec.table_path).resolve()]
    twin = _PKG / "methods" / "heuristic" / mod.name
    if mod.parent == _PKG / "tasks" and twin.is_file():
        own.append(twin)
    shared = [f for e in ROLLOUT_SHARED for f in _files(_PKG / e)]
    deps = [f for t in TASK_DEPENDS.get(task, ()) for f in task_files(t)]
    return sorted(set(shared + own + deps))


def files_hash(files) -> str:
    """sha256 over the files' package-relative names and bytes, in sorted order.

    Parameters
    ----------
    files : iterable of str or os.PathLike
        The files; one outside the package is named by its base name only.

    Returns
    -------
    str
        The hex digest.
    """
    h = hashlib.sha256()
    for f in sorted(Path(p).resolve() for p in files):
        try:
            name = f.relative_to(_PKG).as_posix()
        except ValueError:
            name = f.name
        h.update(name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()


@functools.lru_cache(maxsize=None)
def task_code(task: str) -> str:
    """:func:`files_hash` of :func:`task_files` (cached per process: one workflow parse).

    Parameters
    ----------
    task : str
        A registered task id.

    Returns
    -------
    str
        The hex digest: the code version of the task's rollout cells.
    """
    return files_hash(task_files(task))


def tasks_code(tasks) -> str:
    """The code version of a job over several tasks (e.g. the BC teacher dataset).

    Parameters
    ----------
    tasks : iterable of str
        Registered task ids.

    Returns
    -------
    str
        :func:`files_hash` of the union of their :func:`task_files`.
    """
    return files_hash(sorted({f for t in tasks for f in task_files(t)}))

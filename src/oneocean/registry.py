"""The one registry of tasks, task families and methods.

Everything that lists tasks or methods derives from here: :mod:`oneocean.vocab`
(``TASK_IDS``, ``METHODS``), the config schema's enums (:func:`oneocean.config.load_schema`),
the workflow's ``wildcard_constraints``, the task-module lookup
(:func:`oneocean.tasks.task_module`) and the paper tables.

Tasks are *discovered* from the ``spec:`` block of the tier tables shipped in
``oneocean/data/tasks/<ID>.yaml`` (the paper's ten, in the paper's order, first); a user's or a
test's task whose YAML lives elsewhere is added at run time with
``register_task(load_task_spec(path))``. Methods are declared below (:data:`BUILTIN_METHODS`)
and extended with :func:`register_method`. A plugin is a module that calls these at import;
:func:`load_plugins` (the config key ``plugins``) imports it.

This module is cheap: it imports no numba and no task module (only PyYAML, lazily, when the
packaged tables are first read).
"""

from __future__ import annotations

import importlib
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Iterable, Mapping

from .errors import ConfigError, OneOceanError
from .io import read_yaml_mapping

#: The paper's task ladder, in the paper's order (Table II): canonical order of task ids.
PAPER_TASKS = ("G2G", "SK", "RF", "DPT", "AS", "PI", "FT", "SPC", "UPL", "FH")

#: Built-in task families (the paper's three, Sec. III-C) -> label used in the tables.
BUILTIN_FAMILIES = {
    "navigation": "Navigation / Tracking",
    "sensing": "Sensing / Inspection",
    "coordination": "Coordination / Pollution",
}

#: Method kinds: ``fused`` = jitted per-agent policy inside the episode loop, ``learned`` = a
#: trained network evaluated inside the loop (weights as arrays), ``planner`` = a Python
#: planner called between K-step segments, ``callable`` = Python obs -> action through the
#: step API.
METHOD_KINDS = ("fused", "learned", "planner", "callable")

#: ``better:`` values of a metric in a task spec.
DIRECTIONS = {"higher": True, "lower": False}

_ID = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_MODULE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")


@dataclass(frozen=True)
class TaskSpec:
    """One task: identity, family, implementation, team size, metrics and tier table.

    ``metrics[0]`` is the primary metric; ``higher_is_better[m]`` says which way metric ``m``
    improves (tables bold the best value with it). ``family_label`` (optional) names a new
    family in tables; a known family keeps its label. Invalid fields raise a one-line
    ConfigError.

    Attributes
    ----------
    id : str
        Task id: a letter followed by letters, digits or ``_`` (e.g. ``"G2G"``).
    label : str
        Human label (e.g. ``"Go-to-goal"``).
    family : str
        Family id (:func:`families`).
    module : str
        Dotted name of the module with the task's hooks.
    agents_default : int
        Default team size.
    agents_range : tuple of int
        ``(lo, hi)`` team sizes, ``1 <= lo <= agents_default <= hi``.
    metrics : tuple of str
        Metric column names, the primary first.
    higher_is_better : mapping of str to bool
        Per metric, whether higher is better (a read-only mapping).
    dt_s : float
        Control step, s (> 0).
    table_path : str
        Path of the task's tier-table YAML.
    family_label : str, default ""
        Table label of a new family.
    kernel : str, default ""
        Dotted name of the module binding the compiled loop (default: ``module``).
    """

    id: str
    label: str
    family: str
    module: str
    agents_default: int
    agents_range: tuple[int, int]
    metrics: tuple[str, ...]
    higher_is_better: Mapping[str, bool] = field(hash=False)
    dt_s: float
    table_path: str
    family_label: str = field(default="", compare=False)
    kernel: str = ""

    def __post_init__(self):
        where = f"task spec {self.id!r}"
        if not isinstance(self.id, str) or not _ID.match(self.id):
            raise ConfigError(f"task spec: id {self.id!r} must be a letter followed by letters, "
                              "digits or '_'")
        for name in ("label", "family"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name).strip():
                raise ConfigError(f"{where}: '{name}' must be a non-empty string")
        if not isinstance(self.module, str) or not _MODULE.match(self.module):
            raise ConfigError(f"{where}: 'module' {self.module!r} is not a dotted module name")
        if self.kernel and (not isinstance(self.kernel, str) or not _MODULE.match(self.kernel)):
            raise ConfigError(f"{where}: 'kernel' {self.kernel!r} is not a dotted module name")
        metrics = tuple(self.metrics)
        if not metrics or not all(isinstance(m, str) and m for m in metrics):
            raise ConfigError(f"{where}: 'metrics' must be a non-empty list of names "
                              "(the primary first)")
        if len(set(metrics)) != len(metrics):
            raise ConfigError(f"{where}: duplicate metric in {list(metrics)}")
        hib = dict(self.higher_is_better)
        if set(hib) != set(metrics) or not all(isinstance(v, bool) for v in hib.values()):
            raise ConfigError(f"{where}: 'higher_is_better' must give a bool for exactly the "
                              f"metrics {list(metrics)}")
        lo, hi = (int(v) for v in self.agents_range)
        if not 1 <= lo <= int(self.agents_default) <= hi:
            raise ConfigError(f"{where}: agents default {self.agents_default} outside its "
                              f"range [{lo}, {hi}] (need 1 <= lo <= default <= hi)")
        if not float(self.dt_s) > 0:
            raise ConfigError(f"{where}: 'dt_s' must be > 0 (got {self.dt_s})")
        object.__setattr__(self, "metrics", metrics)
        object.__setattr__(self, "higher_is_better",
                           MappingProxyType({m: hib[m] for m in metrics}))
        object.__setattr__(self, "agents_range", (lo, hi))
        object.__setattr__(self, "agents_default", int(self.agents_default))
        object.__setattr__(self, "dt_s", float(self.dt_s))
        object.__setattr__(self, "table_path", str(self.table_path))
        if self.family_label:
            _check_family_label(self.family, self.family_label, where)

    @property
    def kernel_module(self) -> str:
        """The module binding the task's compiled loop (:mod:`oneocean.kernels`).

        ``kernel``, default ``module``: a plugin may define its kernel beside its hooks.
        """
        return self.kernel or self.module

    @property
    def primary(self) -> str:
        """The primary metric (``metrics[0]``)."""
        return self.metrics[0]


@dataclass(frozen=True)
class MethodSpec:
    """One method: how it runs (``kind``) and what it sees (``information``).

    ``short`` is the column label in tables (defaults to ``label``). Invalid fields raise a
    one-line ConfigError.

    Attributes
    ----------
    name : str
        Method name: a letter followed by letters, digits or ``_``.
    label : str
        Human label.
    kind : str
        How it runs, one of :data:`METHOD_KINDS`.
    information : str
        What it sees (e.g. ``"shared sensor models"``).
    description : str
        One or two sentences for the docs.
    short : str, default ""
        Column label in tables (``""``: ``label``).
    """

    name: str
    label: str
    kind: str
    information: str
    description: str
    short: str = ""

    def __post_init__(self):
        if not isinstance(self.name, str) or not _ID.match(self.name):
            raise ConfigError(f"method spec: name {self.name!r} must be a letter followed by "
                              "letters, digits or '_'")
        if self.kind not in METHOD_KINDS:
            raise ConfigError(f"method spec {self.name!r}: kind {self.kind!r} is not one of "
                              f"{', '.join(METHOD_KINDS)}")
        for name in ("label", "information"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name).strip():
                raise ConfigError(f"method spec {self.name!r}: '{name}' must be a non-empty "
                                  "string")
        if not self.short:
            object.__setattr__(self, "short", self.label)


#: The built-in methods (their policies live with the task code / ``oneocean.methods``).
BUILTIN_METHODS = (
    MethodSpec("heuristic", "Heuristic", "fused", "shared sensor models",
               "The paper's baseline: per-task logic plus a velocity controller toward the "
               "current target within the vehicle's v_max, with feed-forward of its current "
               "estimate (forecast plus filtered in-situ samples) and dead-reckoning "
               "navigation (data/sensors.yaml, the same for every non-oracle method).",
               short="Heur"),
    MethodSpec("oracle", "Oracle", "fused", "true current and position",
               "A privileged solvability check: the true current and its true position, full "
               "v_max and the same task logic (a planner where a task has one). Not a "
               "baseline."),
    MethodSpec("bc", "Behaviour cloning", "learned", "shared sensor models",
               "An MLP trained by MSE on the heuristic teacher's actions (training seeds "
               "disjoint from the evaluation seed), mapping each agent's observation features "
               "to its through-water velocity; the heuristic's mission layer (plan, target "
               "point) is kept, the network replaces its velocity law.", short="BC"),
)

#: Methods shipped in the package that are not built in (the workflow's rollouts never run
#: them by default; their own rules do): name -> ``"module:attribute"`` of its
#: :class:`MethodSpec` (the module registers it at import). :func:`method_spec` registers it
#: on first lookup, so a table reads such a method's cell files in any process.
PACKAGED_METHODS = {"ppo": "oneocean.methods.ppo.policy:METHOD"}

_tasks: dict[str, TaskSpec] | None = None     # id -> spec, canonical order (lazy)
_builtin_tasks: tuple[str, ...] = ()
_families: dict[str, str] = dict(BUILTIN_FAMILIES)
_methods: dict[str, MethodSpec] = {m.name: m for m in BUILTIN_METHODS}
_builtin_methods = tuple(_methods)


# ------------------------------------------------------------------------------ task specs

def _tasks_dir() -> Path:
    return Path(str(resources.files("oneocean") / "data" / "tasks"))


def load_task_spec(path: str | Path) -> TaskSpec:
    """Build a :class:`TaskSpec` from a tier-table YAML.

    From its ``spec:`` block plus its ``agents`` and ``dt_s`` keys; it is not registered
    (see :func:`register_task`). The block::

        spec:
          id: G2G
          label: Go-to-goal
          family: navigation            # a family id (families())
          family_label: ...             # optional, only for a new family
          module: oneocean.tasks.g2g
          kernel: oneocean.kernels.g2g  # optional: the compiled loop (default: module)
          metrics:                      # primary first; better: higher | lower
            - {name: final_error_m, better: lower}

    Parameters
    ----------
    path : path-like
        The tier-table YAML.

    Returns
    -------
    TaskSpec
        The spec (``table_path`` is the resolved path).

    Raises
    ------
    ConfigError
        One line naming the file and key, on a missing, unknown or ill-typed key.
    """
    path = Path(path).resolve()
    doc = read_yaml_mapping(path, "task table")
    spec = doc.get("spec")
    if not isinstance(spec, dict):
        raise ConfigError(f"{path}: missing 'spec' block (id, label, family, module, metrics)")
    for key in ("id", "label", "family", "module", "metrics"):
        if key not in spec:
            raise ConfigError(f"{path}: missing key 'spec.{key}'")
    unknown = sorted(set(spec) - {"id", "label", "family", "family_label", "module", "kernel",
                                  "metrics"})
    if unknown:
        raise ConfigError(f"{path}: unknown key 'spec.{unknown[0]}' (known keys: family, "
                          "family_label, id, kernel, label, metrics, module)")
    for key in ("agents", "dt_s"):
        if key not in doc:
            raise ConfigError(f"{path}: missing key '{key}'")
    agents = doc["agents"]
    if not (isinstance(agents, dict) and "default" in agents and "range" in agents
            and len(agents["range"]) == 2):
        raise ConfigError(f"{path}: key 'agents' must be {{default: N, range: [lo, hi]}}")
    metrics, hib = [], {}
    if not isinstance(spec["metrics"], list):
        raise ConfigError(f"{path}: key 'spec.metrics' must be a list of "
                          "{name: ..., better: higher|lower} (the primary first)")
    for i, m in enumerate(spec["metrics"]):
        if not (isinstance(m, dict) and set(m) == {"name", "better"}
                and m["better"] in DIRECTIONS):
            raise ConfigError(f"{path}: key 'spec.metrics.{i}' must be "
                              "{name: ..., better: higher|lower}")
        metrics.append(str(m["name"]))
        hib[str(m["name"])] = DIRECTIONS[m["better"]]
    try:
        return TaskSpec(id=spec["id"], label=spec["label"], family=spec["family"],
                        module=spec["module"], agents_default=agents["default"],
                        agents_range=tuple(agents["range"]), metrics=tuple(metrics),
                        higher_is_better=hib, dt_s=doc["dt_s"], table_path=str(path),
                        family_label=spec.get("family_label") or "",
                        kernel=spec.get("kernel") or "")
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{path}: {exc}") from None


def _check_family_label(family: str, label, where) -> None:
    if not isinstance(label, str) or not label.strip():
        raise ConfigError(f"{where}: 'spec.family_label' must be a non-empty string")
    known = _families.get(family)
    if known is not None and known != label:
        raise ConfigError(f"{where}: family {family!r} already has the label {known!r} "
                          f"(got {label!r})")


def _discover() -> dict[str, TaskSpec]:
    """The packaged task specs: the paper's ten in paper order, then other packaged tables."""
    global _tasks, _builtin_tasks
    if _tasks is None:
        found = {}
        for f in sorted(_tasks_dir().glob("*.yaml")):
            spec = load_task_spec(f)
            if spec.id != f.stem:
                raise ConfigError(f"{f}: spec.id {spec.id!r} does not match the file name")
            _add_family(spec)
            found[spec.id] = spec
        missing = [t for t in PAPER_TASKS if t not in found]
        if missing:
            raise ConfigError(f"{_tasks_dir()}: no tier table for paper task(s) {missing}")
        order = list(PAPER_TASKS) + sorted(set(found) - set(PAPER_TASKS))
        _tasks = {t: found[t] for t in order}
        _builtin_tasks = tuple(order)
    return _tasks


def _add_family(spec: TaskSpec) -> None:
    if spec.family not in _families:
        _families[spec.family] = spec.family_label or spec.family.capitalize()


def register_task(spec: TaskSpec | str | Path) -> TaskSpec:
    """Register a task at run time (a :class:`TaskSpec`, or the path of its tier-table YAML).

    Registering the same spec again is a no-op. A new family gets its ``family_label``
    (default: the family id capitalised).

    Parameters
    ----------
    spec : TaskSpec or path-like
        The spec, or the path of its tier-table YAML (:func:`load_task_spec`).

    Returns
    -------
    TaskSpec
        The registered spec.

    Raises
    ------
    ConfigError
        Another spec under an existing id (or a bad YAML).
    """
    tasks = _discover()
    if not isinstance(spec, TaskSpec):
        spec = load_task_spec(spec)
    old = tasks.get(spec.id)
    if old is not None:
        if old == spec:
            return old
        raise ConfigError(f"task {spec.id!r} is already registered (table {old.table_path}); "
                          f"cannot register another spec from {spec.table_path}")
    _add_family(spec)
    tasks[spec.id] = spec
    return spec


def unregister_task(task_id: str) -> None:
    """Remove a task registered at run time; an id that is not registered is ignored.

    Parameters
    ----------
    task_id : str
        The task id.

    Raises
    ------
    ConfigError
        If the task is built in (it cannot be removed).
    """
    tasks = _discover()
    if task_id in _builtin_tasks:
        raise ConfigError(f"task {task_id!r} is built in and cannot be unregistered")
    tasks.pop(task_id, None)


def task_ids() -> tuple[str, ...]:
    """Every registered task id.

    Returns
    -------
    tuple of str
        The paper's ladder in its order, other packaged tasks (sorted), then tasks
        registered at run time in registration order.
    """
    return tuple(_discover())


def builtin_task_ids() -> tuple[str, ...]:
    """The task ids shipped with the package.

    Returns
    -------
    tuple of str
        The paper's ladder in its order, then other packaged tasks (sorted).
    """
    _discover()
    return _builtin_tasks


def packaged_task_ids() -> tuple[str, ...]:
    """:func:`builtin_task_ids` from the packaged tier tables' file names, without reading them.

    A table's ``spec.id`` is its file name (:func:`builtin_task_ids` checks it). For callers
    that must stay cheap, such as the Gymnasium registration at ``import oneocean``.

    Returns
    -------
    tuple of str
        The paper's tasks present, in its order, then the other packaged tasks (sorted).
    """
    if _tasks is not None:
        return _builtin_tasks
    stems = {f.stem for f in _tasks_dir().glob("*.yaml")}
    return (tuple(t for t in PAPER_TASKS if t in stems)
            + tuple(sorted(stems - set(PAPER_TASKS))))


def scene_tasks() -> tuple[str, ...]:
    """The registered tasks that run in a scene, on either backend.

    Returns
    -------
    tuple of str
        The tasks whose tier table has a ``scene_tiers`` block, in :func:`task_ids` order.
    """
    return tuple(t for t in task_ids()
                 if read_yaml_mapping(task_spec(t).table_path, "tier table").get("scene_tiers"))


def task_spec(task_id: str) -> TaskSpec:
    """The spec of a registered task.

    Parameters
    ----------
    task_id : str
        The task id.

    Returns
    -------
    TaskSpec
        Its spec.

    Raises
    ------
    ConfigError
        One line listing valid ids, for an unknown id.
    """
    tasks = _discover()
    if task_id not in tasks:
        _invalid("task", task_id, tuple(tasks))
    return tasks[task_id]


def families() -> tuple[str, ...]:
    """Family ids of the registered tasks.

    Returns
    -------
    tuple of str
        In order of first appearance in :func:`task_ids`.
    """
    return tuple(dict.fromkeys(s.family for s in _discover().values()))


def family_label(family: str) -> str:
    """The human label of a family.

    Parameters
    ----------
    family : str
        A family id (built in, declared or of a registered task).

    Returns
    -------
    str
        Its label, e.g. ``"Navigation / Tracking"``.

    Raises
    ------
    ConfigError
        One line listing valid ids, for an unknown family.
    """
    _discover()
    if family not in _families:
        _invalid("family", family, tuple(_families))
    return _families[family]


def register_family(family: str, label: str) -> None:
    """Declare a new family's label (before registering its tasks; optional).

    Parameters
    ----------
    family : str
        The family id: a letter followed by letters, digits or ``_``.
    label : str
        Its table label (non-empty).

    Raises
    ------
    ConfigError
        A bad id or label, or a known family with another label.
    """
    _check_family_label(family, label, f"family {family!r}")
    if not _ID.match(str(family)):
        raise ConfigError(f"family {family!r}: must be a letter followed by letters, digits "
                          "or '_'")
    _families[family] = label


# ------------------------------------------------------------------------------ methods

def register_method(spec: MethodSpec) -> MethodSpec:
    """Register a method; the same spec again is a no-op.

    Parameters
    ----------
    spec : MethodSpec
        The method.

    Returns
    -------
    MethodSpec
        The registered spec.

    Raises
    ------
    ConfigError
        If ``spec`` is not a MethodSpec, or another spec is registered under its name.
    """
    if not isinstance(spec, MethodSpec):
        raise ConfigError(f"register_method: expected a MethodSpec, got {type(spec).__name__}")
    old = _methods.get(spec.name)
    if old is not None:
        if old == spec:
            return old
        raise ConfigError(f"method {spec.name!r} is already registered with another spec")
    _methods[spec.name] = spec
    return spec


def unregister_method(name: str) -> None:
    """Remove a method registered at run time; a name that is not registered is ignored.

    Parameters
    ----------
    name : str
        The method name.

    Raises
    ------
    ConfigError
        If the method is built in (it cannot be removed).
    """
    if name in _builtin_methods:
        raise ConfigError(f"method {name!r} is built in and cannot be unregistered")
    _methods.pop(name, None)


def method_names() -> tuple[str, ...]:
    """Every registered method name.

    Returns
    -------
    tuple of str
        The built-ins, then methods registered at run time in registration order.
    """
    return tuple(_methods)


def builtin_method_names() -> tuple[str, ...]:
    """The built-in methods (the config's default ``rollouts.methods``).

    Returns
    -------
    tuple of str
        The names of :data:`BUILTIN_METHODS`, in order.
    """
    return tuple(m for m in _methods if m in _builtin_methods)


def method_spec(name: str) -> MethodSpec:
    """The spec of a method (a :data:`PACKAGED_METHODS` entry is imported and registered first).

    Parameters
    ----------
    name : str
        The method name.

    Returns
    -------
    MethodSpec
        Its spec.

    Raises
    ------
    ConfigError
        One line listing valid names, for an unknown name.
    """
    if name not in _methods and name in PACKAGED_METHODS:
        mod, attr = PACKAGED_METHODS[name].split(":")
        register_method(getattr(importlib.import_module(mod), attr))
    if name not in _methods:
        _invalid("method", name, tuple(_methods))
    return _methods[name]


# ------------------------------------------------------------------------------ plugins

def load_plugins(modules: Iterable[str] | None) -> list[str]:
    """Import each dotted module name (a plugin registers tasks/methods at import).

    Parameters
    ----------
    modules : list or tuple of str, optional
        Dotted module names (the config key ``plugins``); None: none.

    Returns
    -------
    list of str
        The names imported.

    Raises
    ------
    ConfigError
        One line naming the entry, for ``modules`` that is not a list, a name that is not a
        dotted module name, or a module that cannot be imported.
    """
    if modules is None:
        return []
    if isinstance(modules, str) or not isinstance(modules, (list, tuple)):
        raise ConfigError(f"config key 'plugins': must be a list of module names "
                          f"(got {modules!r})")
    done = []
    for i, name in enumerate(modules):
        if not isinstance(name, str) or not _MODULE.match(name):
            raise ConfigError(f"config key 'plugins.{i}': {name!r} is not a dotted module name")
        try:
            importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name and (name == exc.name or name.startswith(exc.name + ".")):
                raise ConfigError(f"config key 'plugins.{i}': no module named {name!r}") from None
            raise ConfigError(f"config key 'plugins.{i}': plugin {name!r} failed to import "
                              f"(ModuleNotFoundError: {exc})") from None
        except OneOceanError as exc:
            raise ConfigError(f"config key 'plugins.{i}': plugin {name!r}: {exc}") from None
        except Exception as exc:  # noqa: BLE001 - report any import failure in one line
            raise ConfigError(f"config key 'plugins.{i}': plugin {name!r} failed to import "
                              f"({exc.__class__.__name__}: {exc})") from None
        done.append(name)
    return done


def _invalid(what: str, value, options) -> None:
    opts = ", ".join(repr(o) for o in options)
    raise ConfigError(f"{what}: invalid value {value!r}. Valid options are ({opts}).")

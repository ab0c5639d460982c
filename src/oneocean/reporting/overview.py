"""The paper's overview: Table I (the systems compared) and Figs. 1-2.

* :func:`systems_table` (Table I): the systems of ``oneocean/data/systems.yaml``, one row
  each, the paper's columns with their meanings in the caption.
* :func:`plot_registry_overview` (Fig. 1): what is implemented, read from the registry: the
  tasks' tiers on each backend, the data sources of each layer, the methods' kinds.
* :func:`plot_workflow` (Fig. 2): the workflow's rule graph, as Snakemake itself reports it
  (``snakemake --rulegraph dot``, :func:`rule_graph`), laid out in layers by matplotlib (no
  graphviz needed).

Nothing here is drawn by hand: each figure returns the data it drew, which the tests compare
with the registry and with Snakemake's own graph.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from ..io import read_yaml_mapping
from .latex import booktabs
from .tables import _escape

# ------------------------------------------------------------------------------ Table I

#: Cell text of Table I: provided, not provided, unclear in the paper's text.
MARKS = {True: "$\\bullet$", False: "$\\circ$", None: "?"}


def load_systems(path=None) -> dict:
    """The systems file, checked: every system has exactly the file's columns.

    Parameters
    ----------
    path : path-like, optional
        Default: the packaged ``oneocean/data/systems.yaml``.

    Returns
    -------
    dict
        ``columns`` (key -> ``header``, ``meaning``, in the paper's order) and ``systems``
        (a list of ``name, cite, url, venue, transcribed, features`` mappings).
    """
    if path is None:
        path = Path(str(resources.files("oneocean") / "data" / "systems.yaml"))
    data = read_yaml_mapping(path, "systems table")
    cols = list(data["columns"])
    for s in data["systems"]:
        missing = set(cols) ^ set(s["features"])
        if missing:
            raise ValueError(f"systems.yaml: {s['name']!r} has other columns than "
                             f"`columns`: {sorted(missing)}")
        for k, v in s["features"].items():
            if v not in (True, False, None):
                raise ValueError(f"systems.yaml: {s['name']!r} {k}: {v!r} is not "
                                 "true, false or null")
    return data


def systems_frame(path=None) -> pd.DataFrame:
    """Table I as data: one row per system, the file's order.

    Parameters
    ----------
    path : path-like, optional
        As :func:`load_systems`.

    Returns
    -------
    pandas.DataFrame
        ``system, cite, url, venue, transcribed`` and one column per feature key (nullable
        boolean: ``<NA>`` where the paper's cell is unclear).
    """
    data = load_systems(path)
    rows = []
    for s in data["systems"]:
        rows.append({"system": s["name"], "cite": str(s.get("cite") or ""),
                     "url": str(s.get("url") or ""), "venue": str(s.get("venue") or ""),
                     "transcribed": str(s["transcribed"]),
                     **{k: s["features"][k] for k in data["columns"]}})
    df = pd.DataFrame(rows)
    for k in data["columns"]:
        df[k] = df[k].astype("boolean")
    return df


def _tex(text: str) -> str:
    return _escape(str(text).replace("\\", "\\textbackslash{}")).replace("#", r"\#")


def systems_latex(df: pd.DataFrame, columns: dict) -> str:
    """Table I as LaTeX: a ``table*`` with the column meanings in the caption.

    Parameters
    ----------
    df : pandas.DataFrame
        :func:`systems_frame`'s rows.
    columns : dict
        The file's ``columns`` (key -> ``header``, ``meaning``).

    Returns
    -------
    str
        The table (label ``tab:systems``): :data:`MARKS` in the cells.
    """
    keys = list(columns)
    header = ["System", "Ref.", "Venue"] + [_tex(columns[k]["header"]) for k in keys]
    rows = []
    for _, r in df.iterrows():
        cells = [MARKS[None if pd.isna(r[k]) else bool(r[k])] for k in keys]
        rows.append([_tex(r["system"]), _tex(r["cite"]), _tex(r["venue"])] + cells)
    task = " is provided as a task."
    meanings = "; ".join(f"{_tex(columns[k]['header'])}: {_tex(columns[k]['meaning'].rstrip('.'))}"
                         for k in keys if not columns[k]["meaning"].endswith(task))
    tasks = [k for k in keys if columns[k]["meaning"].endswith(task)]
    if tasks:
        meanings += ("; " if meanings else "") + "task columns: the task is provided (" + ", ".join(
            f"{_tex(columns[k]['header'])} {_tex(columns[k]['meaning'][:-len(task)])}"
            for k in tasks) + ")"
    unclear = int(df[keys].isna().to_numpy().sum())
    caption = ("System-level comparison and task coverage (the paper's Table I). "
               "$\\bullet$ provided/available, $\\circ$ not provided, ? unclear: the paper's "
               "text renders both bullets alike, so those cells are left open in "
               f"\\texttt{{oneocean/data/systems.yaml}} ({unclear} cells). Ref.: the paper's "
               "reference number. OneOcean's row is what this code base implements. "
               f"Columns. {meanings}.")
    return booktabs(header, rows, caption, "tab:systems", align="lll" + "c" * len(keys),
                    wide=True)


def systems_table(out_tex, path=None) -> pd.DataFrame:
    """Write Table I and its data as Parquet beside it.

    Parameters
    ----------
    out_tex : path-like
        The ``.tex`` file; the rows go beside it as ``.parquet`` (with the column meanings
        in its record).
    path : path-like, optional
        As :func:`load_systems`.

    Returns
    -------
    pandas.DataFrame
        :func:`systems_frame`'s rows.
    """
    from .tables import _write

    data = load_systems(path)
    df = systems_frame(path)
    meta = {"table": "systems",
            "column_meanings": {k: {"header": v["header"], "meaning": " ".join(v["meaning"].split())}
                        for k, v in data["columns"].items()}}
    _write(df, systems_latex(df, data["columns"]), out_tex, meta)
    return df


# ------------------------------------------------------------------------------ Fig. 1

def registry_matrix() -> pd.DataFrame:
    """What is implemented, from the registry: the matrix Fig. 1 draws.

    Returns
    -------
    pandas.DataFrame
        Long: ``panel, row, column, value`` (bool). Panels: ``"tasks"`` (rows the registered
        tasks; columns ``core T<k>`` for each tier of the task's tier table and
        ``mujoco T<k>`` for each of its ``scene_tiers``), ``"sources"`` (rows the source
        kinds of :data:`oneocean.vocab.SOURCE_KINDS`; columns ``currents`` and
        ``bathymetry``), ``"methods"`` (rows the registered methods; columns the method
        kinds).
    """
    from .. import registry, vocab
    from ..backends.protocol import BACKENDS
    from ..sources import BATHYMETRY_SOURCES, CURRENT_SOURCES
    from ..tasks.tiers import load_task_table

    scene_backends = [b for b in BACKENDS if b != "core"]
    rows = []
    tables = {t: load_task_table(t) for t in registry.task_ids()}
    tiers = sorted({k for tb in tables.values() for k in tb["tiers"]})
    stiers = sorted({k for tb in tables.values() for k in (tb.get("scene_tiers") or {})})
    for t, tb in tables.items():
        for k in tiers:
            rows.append(("tasks", t, f"core T{k}", k in tb["tiers"]))
        for b in scene_backends:
            for k in stiers:
                rows.append(("tasks", t, f"{b} T{k}", k in (tb.get("scene_tiers") or {})))
    for s in vocab.SOURCE_KINDS:
        rows.append(("sources", s, "currents", s in CURRENT_SOURCES))
        rows.append(("sources", s, "bathymetry", s in BATHYMETRY_SOURCES))
    for m in registry.method_names():
        kind = registry.method_spec(m).kind
        for k in registry.METHOD_KINDS:
            rows.append(("methods", m, k, kind == k))
    return pd.DataFrame(rows, columns=["panel", "row", "column", "value"])


def _matrix(ax, sub: pd.DataFrame, colours, title: str, row_labels=None) -> None:
    rows = list(dict.fromkeys(sub["row"]))
    cols = list(dict.fromkeys(sub["column"]))
    val = sub.set_index(["row", "column"])["value"]
    for i, r in enumerate(rows):
        for j, c in enumerate(cols):
            on = bool(val[(r, c)])
            ax.add_patch(_rect(j, i, colours[r] if on else (0.93, 0.93, 0.93)))
    ax.set_xlim(-0.5, len(cols) - 0.5)
    ax.set_ylim(len(rows) - 0.5, -0.5)
    ax.set_xticks(range(len(cols)), cols, rotation=60, ha="right", rotation_mode="anchor")
    ax.set_yticks(range(len(rows)), row_labels or rows)
    ax.tick_params(length=0)
    for s in ax.spines.values():
        s.set_visible(False)
    ax.set_title(title, loc="left")
    ax.set_aspect("equal")


def _rect(x, y, colour):
    from matplotlib.patches import Rectangle

    return Rectangle((x - 0.45, y - 0.45), 0.9, 0.9, facecolor=colour, edgecolor="none")


def _team_label(task: str) -> str:
    """``"SPC (2-10)"``: a task and its team sizes (nothing for a single vehicle)."""
    from .. import registry

    lo, hi = registry.task_spec(task).agents_range
    if hi == 1:
        return task
    return f"{task} ({lo})" if lo == hi else f"{task} ({lo}\u2013{hi})"


def registry_overview_figure(m: pd.DataFrame):
    """Fig. 1 as a matplotlib Figure (call inside :func:`~.figures.paper_style`).

    Parameters
    ----------
    m : pandas.DataFrame
        :func:`registry_matrix`'s rows; a ``True`` is a filled square, a ``False`` a grey one.

    Returns
    -------
    matplotlib.figure.Figure
        Three axes (tasks, sources, methods); each square is a ``Rectangle`` patch.
    """
    from matplotlib.patches import Patch

    from .. import registry
    from .figures import PAGE_IN, new_figure, palette

    fams = list(registry.families())
    pal = palette(max(3, len(fams) + 2))
    fig = new_figure(PAGE_IN, 3.0)
    gs = fig.add_gridspec(1, 3, width_ratios=[3, 1.2, 2])
    tasks = m[m["panel"] == "tasks"]
    colours = {t: pal[fams.index(registry.task_spec(t).family)] for t in tasks["row"]}
    labels = [_team_label(t) for t in dict.fromkeys(tasks["row"])]
    _matrix(fig.add_subplot(gs[0]), tasks, colours, "(a) tasks: tiers per backend",
            row_labels=labels)
    src = m[m["panel"] == "sources"]
    _matrix(fig.add_subplot(gs[1]), src, {s: pal[len(fams)] for s in src["row"]},
            "(b) sources")
    met = m[m["panel"] == "methods"]
    _matrix(fig.add_subplot(gs[2]), met, {s: pal[len(fams) + 1] for s in met["row"]},
            "(c) methods: kind")
    fig.legend(handles=[Patch(color=pal[i], label=registry.family_label(f))
                        for i, f in enumerate(fams)], loc="outside lower center",
               ncols=len(fams))
    return fig


def plot_registry_overview(out_png) -> pd.DataFrame:
    """Fig. 1: the registry's tasks x backends/tiers, sources x layers, methods x kinds.

    Parameters
    ----------
    out_png : path-like
        The PNG; the PDF goes beside it (:func:`oneocean.reporting.figures.save_figure`).

    Returns
    -------
    pandas.DataFrame
        :func:`registry_matrix`'s rows: exactly what is drawn (a filled square is ``True``).
    """
    from .figures import paper_style, save_figure

    m = registry_matrix()
    with paper_style():
        save_figure(registry_overview_figure(m), out_png)
    return m


# ------------------------------------------------------------------------------ Fig. 2

_NODE = re.compile(r'^\s*(\d+)\[label = "([^"]+)"')
_EDGE = re.compile(r"^\s*(\d+)\s*->\s*(\d+)")


def parse_rulegraph(dot: str) -> tuple[list[str], list[tuple[str, str]]]:
    """Rules and edges of ``snakemake --rulegraph dot`` output.

    Parameters
    ----------
    dot : str
        The graph's text.

    Returns
    -------
    rules : list of str
        Rule names, sorted.
    edges : list of (str, str)
        ``(upstream, downstream)``: the downstream rule reads an output of the upstream one;
        sorted.
    """
    names, edges = {}, set()
    for line in dot.splitlines():
        if (n := _NODE.match(line)):
            names[n.group(1)] = n.group(2)
        elif (e := _EDGE.match(line)):
            edges.add((e.group(1), e.group(2)))
    return sorted(names.values()), sorted((names[a], names[b]) for a, b in edges)


def _snakemake_command() -> list[str]:
    """This interpreter's Snakemake, else the ``snakemake`` on ``PATH`` (a rule's conda
    environment, ``--sdm conda``, has the package's runtime only; the workflow's own
    Snakemake stays on ``PATH`` behind it)."""
    import importlib.util
    import shutil

    if importlib.util.find_spec("snakemake") is not None:
        return [sys.executable, "-m", "snakemake"]
    exe = shutil.which("snakemake")
    if exe is None:
        raise RuntimeError("rule_graph: snakemake is neither importable nor on PATH")
    return [exe]


def rule_graph(target: str = "paper_tables", *, snakefile=None, workdir=".",
               config: dict | None = None) -> str:
    """``snakemake --rulegraph dot <target>`` of the workflow (its text).

    Parameters
    ----------
    target : str
        The target rule.
    snakefile : path-like, optional
        Default: the repository's top-level ``Snakefile`` above this package.
    workdir : path-like
        Snakemake's working directory.
    config : dict, optional
        A config (e.g. a job's ``snakemake.config``) written to a file and passed with
        ``--configfile``, so the graph is the one of that run.

    Returns
    -------
    str
        The ``digraph`` text.

    Raises
    ------
    RuntimeError
        Snakemake failed (its last error lines).
    """
    if snakefile is None:
        snakefile = Path(__file__).resolve().parents[3] / "Snakefile"
    cmd = [*_snakemake_command(), "--snakefile", str(snakefile), "--directory", str(workdir),
           "--nolock", "--rulegraph", "dot"]
    with tempfile.TemporaryDirectory(prefix="oneocean-rulegraph-") as tmp:
        if config is not None:
            import yaml

            cf = Path(tmp) / "config.yaml"
            cf.write_text(yaml.safe_dump(json.loads(json.dumps(config, default=str))))
            cmd += ["--configfile", str(cf)]
        cmd += ["--", target]
        run = subprocess.run(cmd, capture_output=True, text=True, cwd=str(workdir),
                             env={**os.environ, "PYTHONWARNINGS": "ignore"})
    if run.returncode != 0 or "digraph" not in run.stdout:
        raise RuntimeError(f"snakemake --rulegraph failed ({run.returncode}): "
                           f"{run.stderr[-2000:]}")
    return run.stdout[run.stdout.index("digraph"):]


#: Stages of the workflow by rule-name prefix (the colours of Fig. 2), first match wins.
STAGES = (("fetch", ("fetch_",)), ("product", ("merge_",)), ("exports", ("export_",)),
          ("rollouts", ("compile_", "rollout_", "bc_")), ("planning", ("planning_",)),
          ("scenes", ("scene_",)), ("figures", ("figure_",)), ("tables", ("table_",)),
          ("targets", ("",)))


def stage_of(rule: str) -> str:
    """The stage of a rule, by its name.

    Parameters
    ----------
    rule : str
        A rule name.

    Returns
    -------
    str
        The first stage of :data:`STAGES` whose prefixes it starts with.
    """
    return next(s for s, prefixes in STAGES if rule.startswith(prefixes))


def layered_layout(rules, edges, sweeps: int = 8) -> dict[str, tuple[int, float]]:
    """Layer (longest path from a source) and order within the layer of each rule.

    Barycentre sweeps order each layer by the mean position of its neighbours in the previous
    (then next) layer; ties are broken by name, so the layout is deterministic.

    Parameters
    ----------
    rules : list of str
        The nodes.
    edges : list of (str, str)
        ``(upstream, downstream)`` pairs (acyclic).
    sweeps : int, default 8
        Barycentre sweeps, alternately forward and backward.

    Returns
    -------
    dict
        rule -> ``(layer, position)``.
    """
    ups = {r: [a for a, b in edges if b == r] for r in rules}
    downs = {r: [b for a, b in edges if a == r] for r in rules}
    layer = {}

    def depth(r):
        if r not in layer:
            layer[r] = 1 + max((depth(u) for u in ups[r]), default=-1)
        return layer[r]

    for r in rules:
        depth(r)
    # pull every rule right, next to its first consumer (a source such as a table without
    # inputs then sits beside the tables, not beside the downloads)
    for r in sorted(rules, key=lambda r: -layer[r]):
        if downs[r]:
            layer[r] = max(layer[r], min(layer[d] for d in downs[r]) - 1)
    n_layers = max(layer.values()) + 1
    order = [sorted(r for r in rules if layer[r] == k) for k in range(n_layers)]
    pos = {r: float(i) for lay in order for i, r in enumerate(lay)}
    for sweep in range(sweeps):
        rng = range(1, n_layers) if sweep % 2 == 0 else range(n_layers - 2, -1, -1)
        for k in rng:
            nb = ups if sweep % 2 == 0 else downs

            def key(r):
                ps = [pos[x] for x in nb[r]]
                return (float(np.mean(ps)) if ps else pos[r], r)

            order[k] = sorted(order[k], key=key)
            for i, r in enumerate(order[k]):
                pos[r] = float(i)
    out = {}
    for k, lay in enumerate(order):
        off = (max(len(o) for o in order) - len(lay)) / 2.0
        for i, r in enumerate(lay):
            out[r] = (k, i + off)
    return out


def _wrap(rule: str, width: int = 15) -> str:
    """A long rule name on two lines, split at the ``_`` nearest its middle."""
    cuts = [i for i, ch in enumerate(rule) if ch == "_"]
    if len(rule) <= width or not cuts:
        return rule
    i = min(cuts, key=lambda i: (abs(i - len(rule) / 2), i))
    return rule[:i] + "_\n" + rule[i + 1:]


def workflow_figure(rules, edges):
    """Fig. 2 as a matplotlib Figure (call inside :func:`~.figures.paper_style`).

    Parameters
    ----------
    rules, edges
        :func:`parse_rulegraph`'s.

    Returns
    -------
    matplotlib.figure.Figure
        One axes: a text box per rule (its name, wrapped at a ``_``), a ``FancyArrowPatch``
        per edge, each carrying its ``(upstream, downstream)`` pair as its ``gid``.
    """
    from matplotlib.patches import FancyArrowPatch, Patch

    from .figures import PAGE_IN, new_figure, palette

    xy = layered_layout(rules, edges)
    stages = [s for s, _ in STAGES]
    pal = palette(len(stages))
    n_layers = max(k for k, _ in xy.values()) + 1
    height = max(p for _, p in xy.values()) + 1
    fig = new_figure(PAGE_IN, max(3.0, 0.24 * height + 0.8))
    ax = fig.add_subplot()
    for a, b in edges:
        (xa, ya), (xb, yb) = xy[a], xy[b]
        # the collecting targets read nearly everything: their edges are drawn faintly
        faint = stage_of(b) == "targets"
        ax.add_patch(FancyArrowPatch((xa + 0.3, ya), (xb - 0.3, yb), arrowstyle="-|>",
                                     mutation_scale=4, lw=0.25 if faint else 0.4,
                                     color=(0.8, 0.8, 0.8) if faint else (0.45, 0.45, 0.45),
                                     shrinkA=0, shrinkB=0, zorder=1 if faint else 2,
                                     gid=f"{a}->{b}"))
    for r in rules:
        x, y = xy[r]
        c = pal[stages.index(stage_of(r))]
        ax.text(x, y, _wrap(r), ha="center", va="center", fontsize=4.0, zorder=3,
                linespacing=0.95, gid=r,
                bbox={"boxstyle": "round,pad=0.25", "fc": (*c, 0.25), "ec": c, "lw": 0.5})
    ax.set_xlim(-0.5, n_layers - 0.5)
    ax.set_ylim(height - 0.4, -0.6)
    ax.set_axis_off()
    used = [s for s in stages if any(stage_of(r) == s for r in rules)]
    fig.legend(handles=[Patch(color=pal[stages.index(s)], label=s) for s in used],
               loc="outside lower center", ncols=len(used))
    return fig


def plot_workflow(dot: str, out_png) -> tuple[list[str], list[tuple[str, str]]]:
    """Fig. 2: the rule graph, layered left (downloads) to right (targets).

    Parameters
    ----------
    dot : str
        ``snakemake --rulegraph dot`` output (:func:`rule_graph`).
    out_png : path-like
        The PNG; the PDF goes beside it.

    Returns
    -------
    rules, edges
        :func:`parse_rulegraph`'s: exactly what is drawn.
    """
    from .figures import paper_style, save_figure

    rules, edges = parse_rulegraph(dot)
    with paper_style():
        save_figure(workflow_figure(rules, edges), out_png)
    return rules, edges

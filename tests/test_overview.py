"""Table I and Figs. 1-2: the systems file, the registry and Snakemake's own rule graph."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest
import yaml

from oneocean import registry, vocab
from oneocean.reporting import overview
from oneocean.reporting.figures import paper_style

REPO = Path(__file__).resolve().parents[1]
SYSTEMS = REPO / "src" / "oneocean" / "data" / "systems.yaml"


@pytest.fixture(scope="module")
def systems():
    return yaml.safe_load(SYSTEMS.read_text())


def test_table_i_rows_are_the_data_files(systems, tmp_path):
    out = tmp_path / "systems.tex"
    df = overview.systems_table(out)
    assert list(df["system"]) == [s["name"] for s in systems["systems"]]
    assert list(df["cite"]) == [s["cite"] for s in systems["systems"]]
    for (_, row), s in zip(df.iterrows(), systems["systems"]):
        for k, v in s["features"].items():
            assert (pd.isna(row[k]) if v is None else bool(row[k]) is v), (s["name"], k)
    back = pd.read_parquet(out.with_suffix(".parquet"))
    pd.testing.assert_frame_equal(back.reset_index(drop=True), df, check_dtype=False)
    tex = out.read_text()
    body = tex[tex.index("\\midrule"):tex.index("\\bottomrule")]
    lines = [ln for ln in body.splitlines() if ln.endswith("\\\\")]
    assert len(lines) == len(systems["systems"])
    marks = {True: "$\\bullet$", False: "$\\circ$", None: "?"}
    for ln, s in zip(lines, systems["systems"]):
        cells = [c.strip() for c in ln[:-2].split(" & ")]
        assert cells[0] == s["name"].replace("_", "\\_")
        assert cells[3:] == [marks[s["features"][k]] for k in systems["columns"]]


def test_table_i_columns_are_the_papers_with_their_meanings(systems, tmp_path):
    # the paper's column order (shared/reference/oneocean_paper.txt, Table I)
    assert [c["header"] for c in systems["columns"].values()] == [
        "Real-data in loop", "Multi-agent", "Cross-backend", "3D currents", "Pollution / spill",
        "Tide modeling", "Canonical task", "Metrics protocol", "Headless batch",
        *registry.PAPER_TASKS]
    assert [s["name"] for s in systems["systems"]] == [
        "MIMIR-UW", "HoloOcean", "HoloOcean 2.0", "OceanSim", "MarineGym", "OceanGym",
        "UNav-Sim", "Stonefish", "Volans", "OneOcean (ours)"]
    tex = (overview.systems_table(tmp_path / "t.tex"), (tmp_path / "t.tex").read_text())[1]
    caption = " ".join(tex[tex.index("\\caption{"):tex.index("\\label")].split())
    for k, c in systems["columns"].items():
        meaning = " ".join(c["meaning"].split()).rstrip(".")
        if k in registry.PAPER_TASKS:
            meaning = meaning.removesuffix(" is provided as a task")
        assert meaning in caption, k
    assert "unclear" in caption


def test_every_system_has_a_citation_and_unclear_cells_say_so(systems):
    for s in systems["systems"]:
        assert s["cite"] and "venue" in s and "url" in s, s["name"]
        assert s["transcribed"] in ("text", "pdf", "implementation")
    assert "unclear" in SYSTEMS.read_text()


def test_oneoceans_task_columns_are_the_registry(systems):
    ours = next(s for s in systems["systems"] if s["transcribed"] == "implementation")
    for t in registry.PAPER_TASKS:
        assert ours["features"][t] is (t in registry.task_ids())
    assert set(ours["evidence"]) == set(systems["columns"]) - set(registry.PAPER_TASKS)


def test_fig1_matrix_is_the_registry(tmp_path):
    from oneocean.sources import BATHYMETRY_SOURCES, CURRENT_SOURCES
    from oneocean.tasks.tiers import load_task_table

    m = overview.plot_registry_overview(tmp_path / "fig1.png")
    assert (tmp_path / "fig1.png").stat().st_size and (tmp_path / "fig1.pdf").stat().st_size
    val = {(p, r, c): v for p, r, c, v in m.itertuples(index=False)}
    tasks = m.loc[m["panel"] == "tasks", "row"].unique().tolist()
    assert tasks == list(registry.task_ids())
    for t in tasks:
        table = load_task_table(t)
        for k in vocab.TIERS:
            assert val[("tasks", t, f"core T{k}")] is (k in table["tiers"])
            assert val[("tasks", t, f"mujoco T{k}")] is (k in (table.get("scene_tiers") or {}))
        assert (val[("tasks", t, "mujoco T1")]) is (t in registry.scene_tasks())
    assert val[("tasks", "G2G", "mujoco T2")] and not val[("tasks", "DPT", "mujoco T2")]
    for s in vocab.SOURCE_KINDS:
        assert val[("sources", s, "currents")] is (s in CURRENT_SOURCES)
        assert val[("sources", s, "bathymetry")] is (s in BATHYMETRY_SOURCES)
    assert val[("sources", "cmems", "currents")] and not val[("sources", "cmems", "bathymetry")]
    for name in registry.method_names():
        for kind in registry.METHOD_KINDS:
            assert val[("methods", name, kind)] is (registry.method_spec(name).kind == kind)
    # what is drawn: one square per cell, grey exactly where the registry says no
    with paper_style():
        fig = overview.registry_overview_figure(m)
    grey = (0.93, 0.93, 0.93, 1.0)
    for ax, panel in zip(fig.axes, ("tasks", "sources", "methods")):
        sub = m[m["panel"] == panel]
        squares = [tuple(p.get_facecolor()) for p in ax.patches]
        assert len(squares) == len(sub)
        assert [sq != grey for sq in squares] == list(sub["value"])


def test_fig2_edges_are_snakemakes_rule_graph(tmp_path):
    dot = overview.rule_graph("paper_tables")
    # Snakemake's own text, read independently of parse_rulegraph
    ids = dict(re.findall(r'^\s*(\d+)\[label = "([^"]+)"', dot, flags=re.M))
    truth = {(ids[a], ids[b]) for a, b in re.findall(r"^\s*(\d+) -> (\d+)", dot, flags=re.M)}
    rules, edges = overview.plot_workflow(dot, tmp_path / "fig2.png")
    assert set(edges) == truth and len(edges) == len(truth)
    assert set(rules) == set(ids.values())
    for known in [("fetch_currents", "merge_variant"), ("fetch_bathymetry", "merge_variant"),
                  ("merge_variant", "export_grid"), ("compile_kernel", "rollout_task"),
                  ("rollout_task", "table_headline"), ("table_systems", "manifest"),
                  ("figure_overview_workflow", "paper_tables")]:
        assert known in truth, known
    assert ("table_headline", "rollout_task") not in truth
    # what is drawn: one arrow per edge, one box per rule, every arrow left to right
    with paper_style():
        fig = overview.workflow_figure(rules, edges)
    ax = fig.axes[0]
    assert sorted(p.get_gid() for p in ax.patches) == sorted(f"{a}->{b}" for a, b in edges)
    assert sorted(t.get_gid() for t in ax.texts) == sorted(rules)
    xy = overview.layered_layout(rules, edges)
    assert all(xy[a][0] < xy[b][0] for a, b in edges)


def test_fig2_layout_is_deterministic():
    rules = ["a", "b", "c", "d"]
    edges = [("a", "c"), ("b", "c"), ("c", "d"), ("a", "d")]
    assert overview.layered_layout(rules, edges) == overview.layered_layout(
        list(reversed(rules)), list(reversed(edges)))
    assert overview.parse_rulegraph('digraph {\n\t0[label = "x", color = "1"];\n'
                                    '\t1[label = "y"];\n\t0 -> 1\n}') == (["x", "y"],
                                                                          [("x", "y")])


def test_table_i_compiles_standalone_and_fits(tmp_path):
    import shutil

    from oneocean.reporting import latex

    if shutil.which("pdflatex") is None:
        pytest.skip("pdflatex not installed")
    overview.systems_table(tmp_path / "systems.tex")
    doc = tmp_path / "doc.tex"
    doc.write_text(latex.standalone_table(tmp_path / "systems.tex"))
    pdf = latex.compile_pdf(doc, tmp_path / "systems.pdf", engine="pdflatex",
                            log_path=tmp_path / "systems.log")
    assert pdf.read_bytes().startswith(b"%PDF")
    assert "Overfull \\hbox" not in (tmp_path / "systems.log").read_text()

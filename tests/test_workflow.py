"""The whole offline DAG on a small synthetic config, through the Snakemake Python API."""

import json
import shutil

import pandas as pd
import pytest

from oneocean.reporting.ablations import stressor_keys
from oneocean.cli import main as cli
from oneocean.engine.recording import read_metrics_meta
from oneocean.tasks.tiers import load_task_table
from oneocean.vocab import VARIANTS
from workflow_helpers import SMALL_CONFIG, need_tex, run_workflow

pytestmark = pytest.mark.slow

REGION = SMALL_CONFIG["region"]["name"]


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    a = tmp_path_factory.mktemp("run_a")
    b = tmp_path_factory.mktemp("run_b")
    run_workflow(a, cores=2)
    run_workflow(b, cores=1)
    return a, b


def test_paper_tables_produces_every_artifact(two_runs):
    a, _ = two_runs
    for v in VARIANTS:
        for rel in (f"product/{REGION}/{v}/product.nc", f"product/{REGION}/{v}/metadata.json",
                    f"exports/{REGION}/{v}/grid.npz", f"exports/{REGION}/{v}/temporal.npz",
                    f"figures/{REGION}/{v}/current_field.png"):
            assert (a / "results" / rel).stat().st_size > 0, rel
    tex = (a / f"results/tables/{REGION}/dataset_variants.tex").read_text()
    assert "\\toprule" in tex and "\\bottomrule" in tex
    for v in VARIANTS:
        assert v in tex
    # every paper table (LaTeX + its numbers) and figure (PNG + PDF) of the region
    for name in ("systems", "task_ladder", "headline", "task_success_by_tier",
                 "difficulty_heuristic", "currents_ablation", "information_ablation",
                 "tier_stressors", "planning_performance", "planning_cost"):
        assert "\\toprule" in (a / f"results/tables/{REGION}/{name}.tex").read_text(), name
        assert len(pd.read_parquet(a / f"results/tables/{REGION}/{name}.parquet")), name
    for name in ("overview_registry", "overview_workflow", "pollution_species", "snapshots",
                 "ladder", "team_sweep", "scene/current_field"):
        for ext in ("png", "pdf"):
            assert (a / f"results/figures/{REGION}/{name}.{ext}").stat().st_size > 1000


def test_scene_backend_stage(two_runs):
    """Scenes built and listed, their cells run on MuJoCo (and on the core in the compare
    scene, the same episodes), Fig. 8's media rendered, the scene tables written."""
    a, _ = two_runs
    sc = SMALL_CONFIG["scenes"]
    v = "scene"
    manifest = json.loads((a / f"results/manifest/{REGION}.json").read_text())["artifacts"]
    for spec in sc["list"]:
        base = f"results/scenes/{REGION}/{v}/{spec['name']}"
        for f in ("scene.xml", "grid.npz", "scene.json"):
            assert f"{base}/{f}" in manifest, f
        assert manifest[f"{base}/scene.xml"]["rule"] == "scene_build"
        media = f"results/figures/{REGION}/scenes/{v}/{spec['name']}"
        for f in ("keyframe_0.png", "keyframe_1.png", "episode.gif"):
            assert (a / media / f).stat().st_size > 1000 and f"{media}/{f}" in manifest
    cells = {}
    for backend in ("mujoco", "core"):
        f = (a / f"results/scene_rollouts/{REGION}/{v}/open_water/{backend}/G2G/tier3/"
             "heuristic.parquet")
        meta = read_metrics_meta(f)
        assert meta["backend"] == backend and meta["scene"] == "open_water"
        assert meta["scene_meta"]["clock"] == {"start_s": meta["scene_meta"]["clock"]["start_s"],
                                               "rate": 1.0}
        cells[backend] = pd.read_parquet(f)
        assert len(cells[backend]) == sc["episodes"] or not meta["applicable"]
    assert list(cells["core"]["candidate"]) == list(cells["mujoco"]["candidate"])
    assert not (a / f"results/scene_rollouts/{REGION}/{v}/pier_harbor/core").exists()
    for name in ("scene_backend", "scene_vs_core"):
        assert "\\toprule" in (a / f"results/tables/{REGION}/{name}.tex").read_text()
    md = (a / f"results/tables/{REGION}/scene_backend.md").read_text()
    assert "PierHarbor*" in md and "OpenWater*" in md and "Core vs scene" in md


def test_tables_state_the_numbers_of_their_cells(two_runs):
    """Table V's and the ablation table's numbers are the cells' own (Wilson rates)."""
    a, _ = two_runs
    r = SMALL_CONFIG["rollouts"]
    root = a / "results/rollouts" / REGION / r["variant"]
    v = pd.read_parquet(a / f"results/tables/{REGION}/task_success_by_tier.parquet")
    for t in r["tasks"]:
        for k in r["tiers"]:
            for m in r["methods"]:
                df = pd.read_parquet(root / f"{t}/tier{k}/{m}.parquet")
                row = v[(v["task"] == t) & (v["tier"] == k) & (v["method"] == m)]
                assert len(row) == 1
                assert row["sr"].iloc[0] == pytest.approx(100 * df["success"].mean())
    ab = pd.read_parquet(a / f"results/tables/{REGION}/currents_ablation.parquet")
    assert len(ab) > 0


def test_rollout_cells_currents_off_and_the_ladder(two_runs):
    """The configured cells only (methods [heuristic]: no oracle cells), the currents-off cells
    of the config default (tier 3, heuristic) on the same episodes, every cell file recording
    its configuration (evaluation seed 1000, the task's vehicle), and the ladder table."""
    a, _ = two_runs
    r = SMALL_CONFIG["rollouts"]
    root = a / "results/rollouts" / REGION / r["variant"]
    cells = {f"{t}/tier{k}/{m}.parquet" for t in r["tasks"] for k in r["tiers"]
             for m in r["methods"]}
    off = {f"{t}/tier3/heuristic_currents-off.parquet" for t in r["tasks"]}
    forced = {f"{t}/tier3/heuristic_{f}.parquet" for t in r["tasks"] for f in ("gain", "tide")}
    team = {f"SPC/tier1/heuristic_n{n}.parquet" for n in (2, 3)}
    info = {f"{t}/tier3/heuristic_info-{lvl}.parquet" for t in r["tasks"]
            for lvl in ("true_current", "true_position", "true_target")}
    # the replicate seed (config default 1001) of the configured methods it replicates
    rep = {f"{t}/tier{k}/heuristic_seed1001.parquet" for t in r["tasks"] for k in r["tiers"]}
    stress = {f"{t}/tier{k}/heuristic_set-{key}-T{4 - k}.parquet" for t in r["tasks"]
              for key in stressor_keys(t) for k in (1, 3)}
    got = {p.relative_to(root).as_posix() for p in root.rglob("*.parquet")}
    assert got == cells | off | forced | team | info | stress | rep
    for rel in sorted(got):
        meta = read_metrics_meta(root / rel)
        df = pd.read_parquet(root / rel)
        task = rel.split("/")[0]
        seed = 1001 if "_seed1001" in rel else 1000
        assert meta["task"] == task and meta["seed"] == seed and r["seed"] == 1000
        assert meta["vehicle"] == load_task_table(task)["vehicle"]
        assert meta["currents"] is (not rel.endswith("_currents-off.parquet"))
        assert (meta["current_gain"] == 2.0) is rel.endswith("_gain.parquet")
        assert (meta["tide"] is not None) is rel.endswith("_tide.parquet")
        if "_n" in rel:
            assert meta["n_agents"] == int(rel.split("_n")[1].split(".")[0])
        assert (df["seed"] == seed).all()
        cols = list(df.columns)
        assert cols[cols.index("seed") + 1] == "candidate"
        episodes = (SMALL_CONFIG["ablations"]["stressors"]["episodes"] if "_set-" in rel
                    else r["episodes"])
        if meta["applicable"]:
            assert len(df) == episodes and meta["reason"] == ""
        else:
            assert len(df) == 0 and meta["reason"]
        # one provenance record per cell, although one job ran all the task's cells
        prov = json.loads((a / "results/provenance/rollouts" / REGION / r["variant"] / rel)
                          .with_suffix(".json").read_text())
        assert prov["rule"] in {"rollout_task", "rollout_task_bc", "rollout_team",
                                f"rollout_ablation_{task}"}, rel
        assert [o["path"] for o in prov["outputs"]] == [
            f"results/rollouts/{REGION}/{r['variant']}/{rel}"]
        assert prov["wildcards"]["task"] == task and prov["params"]["run"]["seed"] == seed
        assert prov["params"]["run"]["currents"] is meta["currents"]
        assert prov["wildcards"].get("tier", str(meta["tier"])) == str(meta["tier"])
        assert f"results/kernels/{REGION}/{r['variant']}/{task}.json" in [
            i["path"] for i in prov["inputs"]]
    # the currents-off ablation replays exactly the same episodes
    for t in r["tasks"]:
        on = pd.read_parquet(root / f"{t}/tier3/heuristic.parquet")
        no = pd.read_parquet(root / f"{t}/tier3/heuristic_currents-off.parquet")
        pd.testing.assert_series_equal(on["candidate"], no["candidate"])
        assert not no["currents"].any() and on["currents"].all()
    ladder = a / f"results/tables/{REGION}/ladder.md"
    md = ladder.read_text()
    assert f"Region `{REGION}`, evaluation seed 1000" in md
    assert "heuristic T1" in md and "heuristic T3 (currents off)" in md and "| oracle T" not in md
    assert "bc T1" in md
    for t in r["tasks"]:
        assert f"| {t} | {load_task_table(t)['vehicle']} |" in md, t
    assert "| Check | Measured | Target | Verdict |" in md
    # the replicate seed's own ladder, and each tier's current in absolute terms
    assert "Replicate: the same ladder on held-out seed 1001" in md
    assert "Macro SR, seed 1000 -> seed 1001: heuristic T1" in md
    assert " m/s, " in md and "share of the vehicle's speed limit" in md
    assert (a / f"results/provenance/tables/{REGION}/ladder.json").is_file()


def test_ablation_tables_from_their_cells_and_in_the_manifest(two_runs):
    """The information-ablation and stressor tables: their numbers are their cells' (the
    'true position' SR is its cell file's success mean), each stressor cell changes exactly
    its one tier key, the ablation cells are not the ladder's, and both tables are
    hash-tracked in the manifest with their provenance."""
    a, _ = two_runs
    r = SMALL_CONFIG["rollouts"]
    root = a / "results/rollouts" / REGION / r["variant"]
    tabs = a / f"results/tables/{REGION}"
    info = pd.read_parquet(tabs / "information_ablation.parquet").set_index("task")
    assert list(info.index) == r["tasks"]
    for t in r["tasks"]:
        for col, name in (("sensors", "heuristic"),
                          ("true_position", "heuristic_info-true_position"),
                          ("true_current", "heuristic_info-true_current"),
                          ("currents_off", "heuristic_currents-off")):
            df = pd.read_parquet(root / f"{t}/tier3/{name}.parquet")
            assert info.loc[t, f"{col}_n"] == len(df) in (0, r["episodes"])
            assert info.loc[t, f"{col}_state"] == ("ok" if len(df) else "n/a")
            assert info.loc[t, f"{col}_sr"] == pytest.approx(100 * df["success"].mean(),
                                                             nan_ok=True)
        assert info.loc[t, "oracle_state"] == "missing"        # the config runs no oracle
        same = info.loc[t, "same_episodes"]
        assert same is pd.NA or bool(same)              # NA: the heuristic's cell is n/a
        meta = read_metrics_meta(root / f"{t}/tier3/heuristic_info-true_current.parquet")
        assert meta["info"] == "true_current" and "tier_overrides" not in meta
    st = pd.read_parquet(tabs / "tier_stressors.parquet")
    assert list(dict.fromkeys(st["task"])) == r["tasks"]
    for t in r["tasks"]:
        table = load_task_table(t)["tiers"]
        rows = st[st["task"] == t].set_index("key")
        assert list(rows.index) == stressor_keys(t)
        t1 = pd.read_parquet(root / f"{t}/tier1/heuristic.parquet")
        for key in rows.index:
            for k, other in ((1, 3), (3, 1)):
                f = root / f"{t}/tier{k}/heuristic_set-{key}-T{other}.parquet"
                meta = read_metrics_meta(f)
                assert meta["tier_overrides"] == {key: table[other][key]}
                changed = {p for p in table[k] if meta["tier_params"][p] != table[k][p]}
                assert changed == {key} and set(meta["tier_params"]) == set(table[k])
            df = pd.read_parquet(root / f"{t}/tier1/heuristic_set-{key}-T3.parquet")
            assert rows.loc[key, "T1_plus_key_sr"] == pytest.approx(
                100 * df["success"].mean(), nan_ok=True)
            assert rows.loc[key, "T1_sr"] == pytest.approx(100 * t1["success"].mean(),
                                                           nan_ok=True)
        assert rows["check"].nunique() == 1
    assert st["over_three_quarters"].dtype == "boolean"
    tex = (tabs / "tier_stressors.tex").read_text()
    assert "Check per task: " + r["tasks"][0] in tex
    manifest = json.loads((a / f"results/manifest/{REGION}.json").read_text())["artifacts"]
    for name, rule in (("information_ablation", "table_information_ablation"),
                       ("tier_stressors", "table_tier_stressors")):
        for ext in ("tex", "parquet"):
            rec = manifest[f"results/tables/{REGION}/{name}.{ext}"]
            assert rec["rule"] == rule
        assert (a / f"results/provenance/tables/{REGION}/{name}.json").is_file()
    key = stressor_keys("G2G")[0]
    cell = manifest[f"results/rollouts/{REGION}/{r['variant']}/G2G/tier1/"
                    f"heuristic_set-{key}-T3.parquet"]
    assert cell["rule"] == "rollout_ablation_G2G"
    assert cell["wildcards"] == {"from_tier": "3", "method": "heuristic", "region": REGION,
                                 "set": key, "task": "G2G", "tier": "1",
                                 "variant": r["variant"]}
    assert cell["params"]["run"]["episodes"] == SMALL_CONFIG["ablations"]["stressors"]["episodes"]
    # the ladder is built from the normal cells only
    ladder = json.loads((a / f"results/provenance/tables/{REGION}/ladder.json").read_text())
    assert not [i for i in ladder["inputs"] if "_info-" in i["path"] or "_set-" in i["path"]]


def test_bc_chain_dataset_weights_rollouts_and_planning_tables(two_runs):
    """dataset -> weights -> bc cells, each step's inputs hash-tracked in the manifest; the
    network is trained on the rollout tasks plus the planning suite's; the planning tables
    have the heuristic and BC rows and say why LLM rows are absent."""
    a, _ = two_runs
    r = SMALL_CONFIG["rollouts"]
    base = f"results/bc/{REGION}/{r['variant']}"
    manifest = json.loads((a / f"results/manifest/{REGION}.json").read_text())["artifacts"]
    w = manifest[f"{base}/weights.npz"]
    assert w["rule"] == "bc_train"
    assert [i["path"] for i in w["inputs"]] == [f"{base}/dataset.parquet"]
    assert w["inputs"][0]["sha256"] == manifest[f"{base}/dataset.parquet"]["sha256"]
    cell = manifest[f"results/rollouts/{REGION}/{r['variant']}/G2G/tier1/bc.parquet"]
    assert f"{base}/weights.npz" in [i["path"] for i in cell["inputs"]]
    data = pd.read_parquet(a / base / "dataset.parquet")
    assert set(data["task"]) == {"G2G", "FT", "SPC"} and set(data["seed"]) == {100}
    assert (data["step"] % SMALL_CONFIG["bc"]["stride"] == 0).all()
    report = json.loads((a / base / "training_report.json").read_text())
    assert report["tasks"] == ["G2G", "FT", "SPC"] and len(report["val_mse"]) == 3
    assert (a / f"results/figures/{REGION}/{r['variant']}/bc_training.png").stat().st_size
    tex = (a / f"results/tables/{REGION}/planning_performance.tex").read_text()
    assert "Heur" in tex and "BC" in tex and "no LLM rows" in tex
    perf = pd.read_parquet(a / f"results/tables/{REGION}/planning_performance.parquet")
    spc = pd.read_parquet(a / f"results/planning/{REGION}/{r['variant']}/SPC/heuristic.parquet")
    heur = perf.set_index("method").loc["heuristic"]
    assert heur["SPC_sr"] == 100.0 * spc["success"].mean()
    assert heur["SPC_metric"] == spc["cleanup_rate"].mean()
    assert read_metrics_meta(a / f"results/planning/{REGION}/{r['variant']}/SPC/bc.parquet")[
        "current_gain"] == 2.0


def test_every_generated_table_compiles_standalone(two_runs, tmp_path):
    """Each table of the paper, as the workflow wrote it, compiles on its own with pdflatex
    and fits the line width (no overfull box)."""
    need_tex("pdflatex")
    from oneocean.reporting import latex

    a, _ = two_runs
    tables = sorted((a / f"results/tables/{REGION}").glob("*.tex"))
    assert len(tables) == 13   # the paper's eleven (Table I included) and the scene backend's two
    for table in tables:
        doc = tmp_path / f"{table.stem}_doc.tex"
        doc.write_text(latex.standalone_table(table))
        log = tmp_path / f"{table.stem}.log"
        pdf = latex.compile_pdf(doc, tmp_path / f"{table.stem}.pdf", engine="pdflatex",
                                log_path=log)
        assert pdf.read_bytes().startswith(b"%PDF"), table.name
        assert "Overfull \\hbox" not in log.read_text(), table.name


def test_paper_target_compiles_and_report_renders(two_runs):
    """`snakemake paper` compiles paper/main.tex with every table and figure of the region
    (byte-identical in both runs); `snakemake --report` renders the report() outputs with
    their captions."""
    a, b = two_runs
    r = _snakemake_cli(a, "--report", "report.html")
    assert r.wait() == 0
    html = (a / "report.html").read_text()
    for needle in ("snapshots.png", "team_sweep.png", "headline.tex", "Fig. 5: one episode",
                   "ladder.md"):
        assert needle in html, needle
    need_tex("latexmk")
    for wd in (a, b):
        assert _snakemake_cli(wd, "--cores", "1", "paper").wait() == 0
    pa = (a / f"results/paper/{REGION}/main.pdf").read_bytes()
    assert pa.startswith(b"%PDF") and pa == (b / f"results/paper/{REGION}/main.pdf").read_bytes()
    log = (a / f"logs/paper/{REGION}/latexmk.log").read_text()
    assert "OneOcean: missing" not in log and "Output written on main.pdf" in log


def test_manifest_tracks_every_artifact_and_verifies(two_runs, monkeypatch):
    a, _ = two_runs
    manifest = json.loads((a / f"results/manifest/{REGION}.json").read_text())["artifacts"]
    produced = {p.relative_to(a).as_posix() for p in (a / "results").rglob("*")
                if p.is_file() and p.suffix in {".nc", ".npz", ".png", ".tex", ".json"}
                and "provenance" not in p.parts and "manifest" not in p.parts}
    assert produced <= set(manifest), produced - set(manifest)
    rec = manifest[f"results/exports/{REGION}/tiny/grid.npz"]
    assert rec["rule"] == "export_grid" and rec["wildcards"]["variant"] == "tiny"
    assert rec["inputs"][0]["path"] == f"results/product/{REGION}/tiny/product.nc"
    assert rec["packages"]["numpy"] and rec["git_commit"]
    assert cli(["verify", str(a / "results")]) == 0


def test_two_runs_are_byte_identical(two_runs):
    a, b = two_runs
    ma = json.loads((a / f"results/manifest/{REGION}.json").read_text())["artifacts"]
    mb = json.loads((b / f"results/manifest/{REGION}.json").read_text())["artifacts"]
    assert set(ma) == set(mb)
    for path, rec in ma.items():  # every artifact, NetCDF included, byte for byte
        assert rec["sha256"] == mb[path]["sha256"], f"{path} differs between runs"


def test_verify_names_a_tampered_artifact(two_runs, tmp_path, capsys):
    a, _ = two_runs
    copy = tmp_path / "copy"
    shutil.copytree(a / "results", copy / "results")
    target = copy / f"results/exports/{REGION}/scene/temporal.npz"
    target.write_bytes(target.read_bytes()[:-8] + b"tampered")
    assert cli(["verify", str(copy / "results")]) == 1
    assert f"exports/{REGION}/scene/temporal.npz" in capsys.readouterr().out


def test_config_typo_fails_before_any_job(tmp_path):
    bad = {**SMALL_CONFIG, "variants": {"tiny": {"resolution_dge": 0.1}}}
    with pytest.raises(Exception, match="variants.tiny.resolution_dge"):
        run_workflow(tmp_path, config=bad)
    assert not (tmp_path / "results").exists()


def _snakemake_cli(workdir, *args):
    """``snakemake`` as a user runs it (a separate process group, so it can be SIGKILLed with
    its jobs)."""
    import subprocess
    import sys

    from workflow_helpers import REPO

    cmd = [sys.executable, "-m", "snakemake", "--snakefile", str(REPO / "Snakefile"),
           "--directory", str(workdir), "--configfile", str(REPO / "config" / "config.yaml"),
           str(workdir / "test_config.yaml"), *args]
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)


def _kill_after(proc, workdir, pattern: str, n: int, timeout: float = 600.0) -> int:
    """SIGKILL ``proc``'s process group once ``n`` files match ``pattern`` under ``workdir``
    (or it ended); returns how many there were."""
    import os
    import signal
    import time

    t0 = time.time()
    while proc.poll() is None and time.time() - t0 < timeout:
        if len(list(workdir.glob(pattern))) >= n:
            break
        time.sleep(0.2)
    got = len(list(workdir.glob(pattern)))
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    return got


def test_killed_runs_recover_with_unlock_and_the_readme_command(two_runs, tmp_path):
    """SIGKILL a run mid-way, then a targeted -R rerun mid-way; `snakemake --unlock` plus the
    README's command then ends with a complete results/ that `oneocean verify` accepts,
    byte-identical to the uninterrupted run."""
    import yaml

    a, _ = two_runs
    wd = tmp_path / "killed"
    wd.mkdir()
    (wd / "test_config.yaml").write_text(yaml.safe_dump(SMALL_CONFIG))
    cells = "results/rollouts/**/*.parquet"
    n1 = _kill_after(_snakemake_cli(wd, "--cores", "2", "paper_tables"), wd, cells, 3)
    assert n1 >= 3 and not (wd / f"results/manifest/{REGION}.json").exists()
    assert _snakemake_cli(wd, "--unlock").wait() == 0
    assert _snakemake_cli(wd, "--cores", "2", "paper_tables").wait() == 0
    # a targeted rerun of every rollout cell, killed after it rewrote some of them
    before = {p: p.stat().st_mtime_ns for p in wd.glob(cells)}
    proc = _snakemake_cli(wd, "--cores", "2", "-R", "rollout_task", "paper_tables")
    import time

    t0 = time.time()
    while proc.poll() is None and time.time() - t0 < 600:
        if sum(p.stat().st_mtime_ns != m for p, m in before.items() if p.exists()) >= 2:
            break
        time.sleep(0.2)
    import os
    import signal

    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert _snakemake_cli(wd, "--unlock").wait() == 0
    assert _snakemake_cli(wd, "--cores", "2", "paper_tables").wait() == 0
    assert cli(["verify", str(wd / "results")]) == 0
    ma = json.loads((a / f"results/manifest/{REGION}.json").read_text())["artifacts"]
    mk = json.loads((wd / f"results/manifest/{REGION}.json").read_text())["artifacts"]
    assert set(mk) == set(ma)
    for path, rec in ma.items():
        assert mk[path]["sha256"] == rec["sha256"], f"{path} differs from the uninterrupted run"

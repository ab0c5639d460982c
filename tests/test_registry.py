"""The one registry: built-in task and method specs, runtime registration, plugins, and
everything that derives from it (vocabulary, schema enums, tier tables, success table)."""

import importlib
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest

from oneocean import registry, vocab
from oneocean.config import load_config, load_schema, validate_config
from oneocean.errors import ConfigError
from workflow_helpers import REPO

DEFAULT = REPO / "config" / "config.yaml"
PAPER = ("G2G", "SK", "RF", "DPT", "AS", "PI", "FT", "SPC", "UPL", "FH")
#: Table II of the paper: team sizes (default, range) and the family of each task.
TEAM = {"G2G": (1, (1, 1)), "SK": (1, (1, 1)), "RF": (1, (1, 1)), "DPT": (1, (1, 1)),
        "AS": (1, (1, 10)), "PI": (1, (1, 10)), "FT": (10, (2, 10)), "SPC": (10, (2, 10)),
        "UPL": (5, (5, 5)), "FH": (8, (8, 8))}
FAMILY = {"G2G": "navigation", "SK": "navigation", "RF": "navigation", "DPT": "navigation",
          "AS": "sensing", "PI": "sensing", "FT": "coordination", "SPC": "coordination",
          "UPL": "coordination", "FH": "coordination"}


def toy_yaml(path: Path, task_id="TOY", family="toys", family_label="Toy tasks",
             metrics=(("score", "higher"), ("miss_m", "lower"))) -> Path:
    lines = [f"  - {{name: {n}, better: {b}}}" for n, b in metrics]
    path.write_text(textwrap.dedent(f"""\
        spec:
          id: {task_id}
          label: Toy task
          family: {family}
          family_label: {family_label}
          module: toy_task_module
          metrics:
        """) + "\n".join("  " + ln for ln in lines) + textwrap.dedent("""
        agents: {default: 2, range: [1, 3]}
        dt_s: 0.5
        harder:
          current_gain: up
        tiers:
          1: {current_gain: 0.5}
          2: {current_gain: 0.7}
          3: {current_gain: 0.9}
        """))
    return path


@pytest.fixture
def clean_registry():
    """Undo every runtime registration a test makes."""
    tasks, methods = registry.task_ids(), registry.method_names()
    families = dict(registry._families)
    yield
    for t in set(registry.task_ids()) - set(tasks):
        registry.unregister_task(t)
    for m in set(registry.method_names()) - set(methods):
        registry.unregister_method(m)
    registry._families.clear()
    registry._families.update(families)


def one_line_error(func, *args, **kwargs) -> str:
    with pytest.raises(ConfigError) as exc:
        func(*args, **kwargs)
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


# ------------------------------------------------------------------------------ built-ins

def test_builtin_task_specs_match_the_paper_and_the_task_modules():
    assert registry.task_ids()[:10] == PAPER
    assert registry.builtin_task_ids() == PAPER
    for task_id in PAPER:
        spec = registry.task_spec(task_id)
        mod = importlib.import_module(spec.module)
        assert mod.TASK_ID == task_id
        assert spec.metrics == tuple(mod.METRICS), task_id
        assert spec.primary == mod.METRICS[0], task_id
        assert tuple(spec.higher_is_better) == spec.metrics
        assert (spec.agents_default, spec.agents_range) == TEAM[task_id], task_id
        assert spec.family == FAMILY[task_id], task_id
        assert spec.dt_s == 1.0
        assert Path(spec.table_path).name == f"{task_id}.yaml" and Path(spec.table_path).is_file()
        assert spec.label and spec.label != task_id
    # directions: errors and times improve downward, rates and successes upward
    hib = {t: registry.task_spec(t).higher_is_better for t in PAPER}
    assert hib["G2G"]["final_error_m"] is False
    assert hib["AS"]["coverage_fraction"] is True
    assert hib["SPC"]["cleanup_rate"] is True and hib["SPC"]["time_to_target_s"] is False
    assert hib["UPL"]["lift_success"] is True and hib["UPL"]["final_object_depth_m"] is False
    assert hib["FH"]["containment_success"] is True
    assert registry.task_spec("SK").label == "Station keeping"


def test_families_in_paper_order_with_table_labels():
    assert registry.families() == ("navigation", "sensing", "coordination")
    assert [registry.family_label(f) for f in registry.families()] == [
        "Navigation / Tracking", "Sensing / Inspection", "Coordination / Pollution"]


def test_builtin_methods():
    assert registry.method_names()[:2] == ("heuristic", "oracle")
    h, o = registry.method_spec("heuristic"), registry.method_spec("oracle")
    assert (h.kind, o.kind) == ("fused", "fused")
    assert "sensor" in h.information and "true" in o.information
    assert h.short == "Heur" and o.short == "Oracle"


def test_vocab_views_follow_the_registry(clean_registry, tmp_path):
    from oneocean.vocab import METHODS, TASK_IDS

    assert tuple(TASK_IDS) == PAPER and TASK_IDS == PAPER and list(METHODS) == [
        "heuristic", "oracle", "bc"]
    registry.register_task(toy_yaml(tmp_path / "toy.yaml"))
    registry.register_method(registry.MethodSpec("mine", "Mine", "callable", "obs", "test"))
    assert TASK_IDS[-1] == "TOY" and len(TASK_IDS) == 11 and "TOY" in vocab.TASK_IDS
    assert "mine" in METHODS


@pytest.mark.parametrize("func, bad, what", [(registry.task_spec, "G2X", "task"),
                                             (registry.method_spec, "mpc", "method"),
                                             (registry.family_label, "swarm", "family")])
def test_unknown_name_is_a_one_line_error_listing_valid_ones(func, bad, what):
    msg = one_line_error(func, bad)
    assert msg.startswith(f"{what}:") and repr(bad) in msg
    valid = {"task": "'G2G'", "method": "'heuristic'", "family": "'navigation'"}[what]
    assert valid in msg


def test_task_module_uses_the_registry():
    from oneocean.tasks import task_module

    assert task_module("AS").__name__ == "oneocean.tasks.as_"
    assert "'NOPE'" in one_line_error(task_module, "NOPE")


def test_registry_import_is_cheap():
    code = ("import sys, oneocean.registry as r, oneocean.config, oneocean.vocab; r.task_ids();"
            " oneocean.config.load_schema();"
            " bad = [m for m in sys.modules if m == 'numba' or m.startswith('oneocean.tasks')];"
            " assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO)


# ------------------------------------------------------------------------------ registration

def test_registered_toy_task_is_everywhere(clean_registry, tmp_path):
    spec = registry.register_task(registry.load_task_spec(toy_yaml(tmp_path / "toy.yaml")))
    assert spec.id == "TOY" and spec.primary == "score"
    assert dict(spec.higher_is_better) == {"score": True, "miss_m": False}
    assert (spec.agents_default, spec.agents_range, spec.dt_s) == (2, (1, 3), 0.5)
    assert registry.task_ids() == PAPER + ("TOY",)
    assert registry.families()[-1] == "toys" and registry.family_label("toys") == "Toy tasks"
    # the schema enum and validation
    enum = load_schema()["properties"]["rollouts"]["properties"]["tasks"]["items"]["enum"]
    assert enum == list(PAPER) + ["TOY"]
    cfg = load_config(DEFAULT, overrides={"rollouts": {"tasks": ["G2G", "TOY"]}})
    assert cfg["rollouts"]["tasks"] == ["G2G", "TOY"]
    # the default task list stays the paper's ladder
    assert validate_config({})["rollouts"]["tasks"] == list(PAPER)
    # its tier table is read from where its YAML lives
    from oneocean.tasks.tiers import load_task_table, tier_params

    assert load_task_table("TOY")["agents"] == {"default": 2, "range": [1, 3]}
    assert tier_params("TOY", 2) == {"current_gain": 0.7}
    # registering the same spec again is a no-op; another spec under the id is an error
    assert registry.register_task(toy_yaml(tmp_path / "toy.yaml")) == spec
    other = toy_yaml(tmp_path / "other.yaml", metrics=(("score", "lower"),))
    assert "'TOY' is already registered" in one_line_error(registry.register_task, other)
    registry.unregister_task("TOY")
    assert "TOY" not in registry.task_ids()
    assert "built in" in one_line_error(registry.unregister_task, "G2G")


def test_unregistered_task_fails_validation_naming_the_key():
    msg = one_line_error(load_config, DEFAULT, overrides={"rollouts": {"tasks": ["TOY"]}})
    assert "rollouts.tasks.0" in msg and "'TOY'" in msg


@pytest.mark.parametrize("edit, named", [
    (lambda t: t.replace("  label: Toy task\n", ""), "spec.label"),
    (lambda t: t.replace("better: higher", "better: up"), "spec.metrics.0"),
    (lambda t: t.replace("module: toy_task_module", "module: not a module"), "module"),
    (lambda t: t.replace("{default: 2, range: [1, 3]}", "{default: 5, range: [1, 3]}"),
     "agents default 5"),
    (lambda t: t.replace("id: TOY", "id: 9TOY"), "id"),
    (lambda t: t.replace("dt_s: 0.5\n", ""), "'dt_s'"),
])
def test_bad_task_spec_is_named_in_one_line(tmp_path, edit, named):
    f = toy_yaml(tmp_path / "toy.yaml")
    f.write_text(edit(f.read_text()))
    msg = one_line_error(registry.load_task_spec, f)
    assert named in msg
    assert "toy.yaml" in msg or "TOY" in msg


def test_unknown_method_in_config_is_named():
    msg = one_line_error(load_config, DEFAULT, overrides={"rollouts": {"methods": ["mpc"]}})
    assert "rollouts.methods.0" in msg and "'mpc'" in msg


def test_registered_method_is_accepted(clean_registry):
    spec = registry.MethodSpec("mpc", "MPC", "planner", "true current field", "test planner")
    registry.register_method(spec)
    assert registry.method_spec("mpc") is spec and registry.method_names()[-1] == "mpc"
    enum = load_schema()["properties"]["rollouts"]["properties"]["methods"]["items"]["enum"]
    assert enum == ["heuristic", "oracle", "bc", "mpc"]
    cfg = load_config(DEFAULT, overrides={"rollouts": {"methods": ["heuristic", "mpc"]}})
    assert cfg["rollouts"]["methods"] == ["heuristic", "mpc"]
    clash = registry.MethodSpec("mpc", "MPC2", "planner", "true current field", "other")
    assert "already registered" in one_line_error(registry.register_method, clash)
    assert "kind" in one_line_error(registry.MethodSpec, "x", "X", "jit", "probe", "")


# ------------------------------------------------------------------------------ plugins

@pytest.mark.parametrize("plugins, named", [
    (["no_such_oneocean_plugin"], "no_such_oneocean_plugin"),
    (["oneocean.no_such_module"], "oneocean.no_such_module"),
    ("just_a_string", "plugins"),
])
def test_bad_plugin_is_a_one_line_error(plugins, named):
    msg = one_line_error(validate_config, {"plugins": plugins})
    assert named in msg and "plugins" in msg
    assert named in one_line_error(registry.load_plugins, plugins)


def test_plugin_that_fails_inside_is_named(tmp_path, monkeypatch):
    (tmp_path / "broken_oneocean_plugin.py").write_text("import no_such_dependency_xyz\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    msg = one_line_error(registry.load_plugins, ["broken_oneocean_plugin"])
    assert "broken_oneocean_plugin" in msg and "no_such_dependency_xyz" in msg


def test_plugin_registers_task_and_method_before_validation(clean_registry, tmp_path,
                                                             monkeypatch):
    toy_yaml(tmp_path / "PLUG.yaml", task_id="PLUG")
    (tmp_path / "toy_oneocean_plugin.py").write_text(textwrap.dedent("""\
        from pathlib import Path
        from oneocean.registry import MethodSpec, load_task_spec, register_method, register_task

        register_task(load_task_spec(Path(__file__).with_name("PLUG.yaml")))
        register_method(MethodSpec("plug_policy", "Plug", "callable", "obs", "a test policy"))
        """))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "toy_oneocean_plugin", raising=False)
    overrides = {"rollouts": {"tasks": ["PLUG"], "methods": ["plug_policy"]}}
    with pytest.raises(ConfigError, match=r"rollouts\.(tasks|methods)\.0"):
        load_config(DEFAULT, overrides=overrides)
    cfg = load_config(DEFAULT, overrides={"plugins": ["toy_oneocean_plugin"], **overrides})
    assert cfg["plugins"] == ["toy_oneocean_plugin"]
    assert "PLUG" in registry.task_ids() and "plug_policy" in registry.method_names()
    monkeypatch.delitem(sys.modules, "toy_oneocean_plugin")


# ------------------------------------------------------------------------------ tables

def _cells(tmp_path, tasks):
    files = []
    for task, n, success in tasks:
        for method in ("oracle", "heuristic"):
            for tier in (2, 1):
                f = tmp_path / f"{task}_{method}_{tier}.parquet"
                pd.DataFrame({"task": task, "method": method, "tier": tier, "n_agents": n,
                              "success": success}).to_parquet(f)
                files.append(f)
    return files


def test_success_table_follows_the_registry(clean_registry, tmp_path):
    from oneocean.reporting.tables import task_success_frame

    cells = _cells(tmp_path, [("FH", 8, [True, False]), ("TOY", 2, [True, True]),
                              ("G2G", 1, [False, False]), ("SPC", 10, [True, False])])
    msg = one_line_error(task_success_frame, cells)       # TOY not registered: not dropped
    assert "'TOY'" in msg
    registry.register_task(toy_yaml(tmp_path / "toy.yaml"))
    df = task_success_frame(cells)
    assert list(df["Task"]) == ["G2G", "SPC", "FH", "TOY", "Macro"]
    assert list(df["Family"]) == ["Navigation / Tracking", "Coordination / Pollution",
                                  "Coordination / Pollution", "Toy tasks", ""]
    assert list(df.columns) == ["Family", "Task", "N", "Heur T1", "Heur T2", "Oracle T1",
                                "Oracle T2"]
    assert list(df["Heur T1"]) == [0.0, 50.0, 50.0, 100.0, 50.0]
    assert list(df["N"][:4]) == [1, 10, 8, 2]

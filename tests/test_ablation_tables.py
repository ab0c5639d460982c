"""What drives a ladder cell (oneocean.reporting.ablations): the information-ablation table and the
stressor table against the cell files they come from, the share of the T1 -> T3 drop and its
3/4 flag, the tier-override mechanism of a cell, and ablation cells kept apart from the
ladder's normal cells."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from oneocean.reporting import ablations as A
from oneocean.reporting import cells as C
from oneocean import registry
from oneocean.reporting import tables as T
from oneocean.config import load_config
from oneocean.engine.recording import read_metrics_meta, write_metrics
from oneocean.errors import ConfigError
from oneocean.reporting.cells import ladder_frame, load_cells, read_cell
from oneocean.reporting.stats import wilson
from oneocean.tasks.tiers import load_task_table
from workflow_helpers import REPO

N = 20
TASKS = ("G2G", "SK", "UPL")
#: Each task's primary metric and vehicle as its registry entry and tier table say (the tier
#: values themselves are read from the tables: they are recalibrated, these tests must not
#: depend on them).
PRIMARY = {t: registry.task_spec(t).primary for t in TASKS}
VEHICLE = {t: load_task_table(t)["vehicle"] for t in TASKS}
AGENTS = {t: registry.task_spec(t).agents_default for t in TASKS}


def write_cell(path, task, tier, method, success, *, currents=True, info=None,
               overrides=None, applicable=True, seed=1000, metric=None, extra=None):
    """A cell file as ``oneocean.tasks.rollout_to_file`` writes it (its record says what it
    is: ``info``, ``tier_overrides``); ``applicable=False``: zero rows. Returns the frame."""
    success = np.asarray(success, dtype=bool) if applicable else np.zeros(0, dtype=bool)
    n = success.size
    if metric is None:
        metric = np.linspace(1.0, 2.0, n)
    metric = np.asarray(metric, dtype=np.float64)[:n]
    df = pd.DataFrame({
        "task": [task] * n, "tier": np.full(n, tier, np.int64), "method": [method] * n,
        "n_agents": np.full(n, AGENTS[task], np.int64), "currents": np.full(n, currents, bool),
        "episode": np.arange(n, dtype=np.int64), "seed": np.full(n, seed, np.int64),
        "candidate": np.arange(n, dtype=np.int64) * 2, "success": success,
        "T_s": np.full(n, 500.0), "E": np.full(n, 1000.0), "coll_ratio": np.zeros(n),
        "violations": np.zeros(n, np.int64), "primary": metric, PRIMARY[task]: metric})
    params = dict(load_task_table(task)["tiers"][tier])
    params.update(overrides or {})
    meta = {"task": task, "tier": int(tier), "method": method, "dynamics": "6dof",
            "vehicle": VEHICLE[task], "n_agents": AGENTS[task], "episodes": n, "seed": seed,
            "current_gain": 1.0, "tide": None, "currents": currents, "tier_params": params,
            "applicable": bool(applicable),
            "reason": "" if applicable else f"{task} tier {tier}: no site deep enough"}
    if info is not None:
        meta["info"] = info
    if overrides:
        meta["tier_overrides"] = overrides
    meta.update(extra or {})
    write_metrics(df, path, meta=meta)
    return df


def _ok(k: int, n: int = N) -> np.ndarray:
    return np.arange(n) < k


# ------------------------------------------------------------------------------ information

@pytest.fixture(scope="module")
def info_cells(tmp_path_factory):
    """Tier 3 of G2G and SK: the heuristic's own cell, true current, true position, currents
    off, the oracle; UPL: not hostable at Tier 3 (every cell n/a)."""
    root = tmp_path_factory.mktemp("info")
    ks = {"G2G": {"own": 10, "true_current": 13, "true_position": 17, "off": 19, "oracle": 20},
          "SK": {"own": 6, "true_current": 15, "true_position": 7, "off": 16, "oracle": 20}}
    files, frames = [], {}
    for task, k in ks.items():
        for cond, kk in k.items():
            f = root / f"{task}_{cond}.parquet"
            method = "oracle" if cond == "oracle" else "heuristic"
            info = cond if cond.startswith("true_") else None
            metric = np.linspace(0.5, 3.0, N) * (1 + kk / 10)
            if task == "SK":    # NaN where the vehicle never held station
                metric = np.where(_ok(kk), metric, np.nan)
            frames[(task, cond)] = write_cell(f, task, 3, method, _ok(kk), info=info,
                                              currents=cond != "off", metric=metric)
            files.append(f)
    for cond in ("own", "true_current", "true_position", "off", "oracle"):
        f = root / f"UPL_{cond}.parquet"
        write_cell(f, "UPL", 3, "oracle" if cond == "oracle" else "heuristic", [],
                   info=cond if cond.startswith("true_") else None, currents=cond != "off",
                   applicable=False)
        files.append(f)
    return files, frames


def test_information_table_states_its_cells_numbers(info_cells, tmp_path):
    files, frames = info_cells
    df = A.information_table(files, tmp_path / "info.tex", tier=3, region="test_coast")
    assert list(df["task"]) == ["G2G", "SK", "UPL"]          # registry order, one row each
    r = df.set_index("task")
    cols = {"sensors": "own", "true_current": "true_current",
            "true_position": "true_position", "currents_off": "off", "oracle": "oracle"}
    for task in ("G2G", "SK"):
        for col, cond in cols.items():
            ep = frames[(task, cond)]
            k, n = int(ep["success"].sum()), len(ep)
            # the SR is the success mean of the cell file it came from, the interval the
            # Wilson interval of that count
            assert r.loc[task, f"{col}_sr"] == pytest.approx(100.0 * ep["success"].mean())
            lo, hi = wilson(k, n)
            assert (r.loc[task, f"{col}_lo"], r.loc[task, f"{col}_hi"]) == pytest.approx(
                (100.0 * lo, 100.0 * hi))
            assert (r.loc[task, f"{col}_k"], r.loc[task, f"{col}_n"]) == (k, n)
            # the primary metric: the mean over the episodes where it is defined
            assert r.loc[task, f"{col}_metric"] == pytest.approx(np.nanmean(ep[PRIMARY[task]]))
            assert r.loc[task, f"{col}_metric_lo"] <= r.loc[task, f"{col}_metric"] \
                <= r.loc[task, f"{col}_metric_hi"]
            assert r.loc[task, f"{col}_state"] == "ok"
        assert r.loc[task, "primary"] == PRIMARY[task]
        assert bool(r.loc[task, "same_episodes"])
    assert r.loc["UPL", "sensors_state"] == "n/a" and math.isnan(r.loc["UPL", "sensors_sr"])
    assert "no site deep enough" in r.loc["UPL", "reason"]
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "info.parquet"), df,
                                  check_dtype=False)
    assert read_metrics_meta(tmp_path / "info.parquet")["table"] == "information_ablation"
    tex = (tmp_path / "info.tex").read_text()
    header = next(ln for ln in tex.splitlines() if ln.startswith("Task &"))
    assert header.split(" & ")[2:] == ["Sensors", "True current", "True position",
                                       "Currents off", "Oracle \\\\"]
    g2g = next(ln for ln in tex.splitlines() if ln.startswith("G2G &"))
    assert g2g.split(" & ")[4] == "85 [64, 95]"        # 17/20 with its Wilson interval
    upl = next(ln for ln in tex.splitlines() if ln.startswith("UPL &"))
    assert upl.split(" & ")[2:] == ["n/a"] * 4 + ["n/a \\\\"]
    # the caption says what each column is, and why UPL is n/a
    for words in ("true current instead of its estimate", "true position instead of its",
                  "switched off", "privileged oracle", "no site deep enough",
                  "Wilson 95\\% interval", "checked"):
        assert words in tex, words
    again = A.information_table(list(reversed(files)), tmp_path / "again.tex", tier=3,
                                region="test_coast")
    pd.testing.assert_frame_equal(again, df)
    assert (tmp_path / "again.tex").read_bytes() == (tmp_path / "info.tex").read_bytes()


def test_ablation_cells_never_pool_with_the_ladders(info_cells):
    """The information cells carry their level in their record: the ladder and Table V see
    only the heuristic's own cell; the forcing ablation only its forcing conditions."""
    files, frames = info_cells
    lad = ladder_frame(load_cells(files))
    g = lad[(lad["task"] == "G2G") & (lad["method"] == "heuristic") & lad["currents"]]
    assert len(g) == 1 and g["sr"].iloc[0] == 100.0 * frames[("G2G", "own")]["success"].mean()
    cells = C.load_cell_frames(files)
    g2g = cells[(cells["task"] == "G2G") & (cells["method"] == "heuristic")]
    assert sorted(g2g["condition"]) == ["currents-off", "data-grounded", "info-true_current",
                                        "info-true_position"]
    assert set(g2g.loc[g2g["ablation"], "info"]) == {"true_current", "true_position"}
    ts = T.task_success_ci_frame(files).set_index(["task", "method", "tier"])
    assert ts.loc[("G2G", "heuristic", 3), "sr"] == 50.0
    ab = T.ablation_frame(files)
    assert set(ab["condition"]) == {"data-grounded", "currents-off"}


# ------------------------------------------------------------------------------ stressors

def test_drop_share_formula():
    assert A.drop_share(100.0, 50.0, 40.0) == pytest.approx(50.0 / 60.0)
    assert A.drop_share(90.0, 90.0, 30.0) == 0.0
    assert A.drop_share(80.0, 20.0, 40.0) == pytest.approx(1.5)    # beyond the whole drop
    assert A.drop_share(60.0, 50.0, 40.0) == pytest.approx(0.5)
    assert math.isnan(A.drop_share(60.0, 50.0, 59.5))              # drop < 1 point: n/a
    assert math.isnan(A.drop_share(40.0, 30.0, 60.0))              # no drop at all
    assert math.isnan(A.drop_share(100.0, math.nan, 40.0))
    assert A.drop_share(41.0, 40.0, 40.0) == 1.0                   # exactly 1 point


def test_stressor_keys_are_the_tier_keys_that_differ():
    for task in ("G2G", "RF", "AS", "FH"):
        tb = load_task_table(task)
        t1, t3 = tb["tiers"][1], tb["tiers"][3]
        keys = A.stressor_keys(task)
        assert keys == [k for k in tb["harder"] if t1[k] != t3[k]]
        cells = A.stressor_cells(task)
        assert len(cells) == 2 * len(keys)
        for c in cells:
            src = t3 if c["tier"] == 1 else t1
            assert c["overrides"] == {c["key"]: src[c["key"]]}
            assert c["from_tier"] == (3 if c["tier"] == 1 else 1)


def test_stressor_keys_leave_out_equal_and_missing_values(monkeypatch):
    import oneocean.tasks.tiers as tiers

    fake = {"harder": {"a": "up", "same": "up", "only_t1": "down", "b": "down"},
            "tiers": {1: {"a": 1, "same": 5, "only_t1": 2, "b": [0.0, 0.5]},
                      3: {"a": 3, "same": 5.0, "b": [0.5, 1.0]}}}
    monkeypatch.setattr(tiers, "load_task_table", lambda task: fake)
    assert A.stressor_keys("X") == ["a", "b"]
    assert A.stressor_cells("X") == [
        {"tier": 1, "key": "a", "from_tier": 3, "overrides": {"a": 3}},
        {"tier": 3, "key": "a", "from_tier": 1, "overrides": {"a": 1}},
        {"tier": 1, "key": "b", "from_tier": 3, "overrides": {"b": [0.5, 1.0]}},
        {"tier": 3, "key": "b", "from_tier": 1, "overrides": {"b": [0.0, 0.5]}}]


#: G2G's tier keys (from its table), the first the dominant one of the fixture below.
G_KEYS = A.stressor_keys("G2G")
TOP = G_KEYS[0]


@pytest.fixture(scope="module")
def stressor_cells(tmp_path_factory):
    """G2G: T1 20/20, T3 8/20 (a 60-point drop); its first tier key alone at Tier 1 gives
    10/20 (share 10/12 = 0.83 > 3/4), the others 20, 17, 14, ... (shares 0, 0.25, 0.5).
    SK: T1 = T3 (no drop). UPL: T3 n/a."""
    assert len(G_KEYS) >= 2
    root = tmp_path_factory.mktemp("stress")
    files = []

    def add(name, *args, **kw):
        f = root / f"{name}.parquet"
        write_cell(f, *args, **kw)
        files.append(f)

    add("g1", "G2G", 1, "heuristic", _ok(20))
    add("g3", "G2G", 3, "heuristic", _ok(8))
    plus = {k: 10 if i == 0 else (20, 17, 14)[(i - 1) % 3] for i, k in enumerate(G_KEYS)}
    minus = {k: 8 + i for i, k in enumerate(G_KEYS)}
    tiers = load_task_table("G2G")["tiers"]
    for key in A.stressor_keys("G2G"):
        add(f"g1_{key}", "G2G", 1, "heuristic", _ok(plus[key]),
            overrides={key: tiers[3][key]}, metric=np.full(N, 9.0))
        add(f"g3_{key}", "G2G", 3, "heuristic", _ok(minus[key]),
            overrides={key: tiers[1][key]})
    add("s1", "SK", 1, "heuristic", _ok(18))
    add("s3", "SK", 3, "heuristic", _ok(18))
    sk = load_task_table("SK")["tiers"]
    for key in A.stressor_keys("SK"):
        add(f"s1_{key}", "SK", 1, "heuristic", _ok(12), overrides={key: sk[3][key]})
        add(f"s3_{key}", "SK", 3, "heuristic", _ok(18), overrides={key: sk[1][key]})
    add("u1", "UPL", 1, "heuristic", _ok(20))
    add("u3", "UPL", 3, "heuristic", [], applicable=False)
    return files, plus, minus


def test_stressor_table_shares_flag_and_check(stressor_cells, tmp_path):
    files, plus, minus = stressor_cells
    df = A.stressor_table(files, tmp_path / "st.tex", region="test_coast")
    g = df[df["task"] == "G2G"].set_index("key")
    assert list(g.index) == A.stressor_keys("G2G")
    tiers = load_task_table("G2G")["tiers"]
    for key in g.index:
        r = g.loc[key]
        assert json.loads(r["low_value"]) == tiers[1][key]
        assert json.loads(r["high_value"]) == tiers[3][key]
        assert (r["T1_sr"], r["T3_sr"]) == (100.0, 40.0)
        assert r["T1_plus_key_sr"] == pytest.approx(100.0 * plus[key] / N)
        assert r["T3_minus_key_sr"] == pytest.approx(100.0 * minus[key] / N)
        lo, hi = wilson(plus[key], N)
        assert (r["T1_plus_key_lo"], r["T1_plus_key_hi"]) == pytest.approx(
            (100 * lo, 100 * hi))
        assert r["drop"] == 60.0
        assert r["share"] == pytest.approx((100.0 - 100.0 * plus[key] / N) / 60.0)
        assert r["share_state"] == "ok"
        assert bool(r["over_three_quarters"]) == bool(r["share"] > 0.75)
    assert g.loc[TOP, "share"] == pytest.approx(50.0 / 60.0)
    assert bool(g.loc[TOP, "over_three_quarters"])
    assert g["over_three_quarters"].sum() == 1
    assert set(g["check"]) == {"FAIL"} and g["check_note"].iloc[0] == f"{TOP} 0.83"
    # no drop: shares n/a, the flag NA, the check n/a
    s = df[df["task"] == "SK"]
    assert s["share"].isna().all() and s["over_three_quarters"].isna().all()
    assert set(s["share_state"]) == {"small drop"} and set(s["check"]) == {"n/a"}
    # a tier the region cannot host: n/a with its reason
    u = df[df["task"] == "UPL"]
    assert len(u) == len(A.stressor_keys("UPL")) and set(u["T3_state"]) == {"n/a"}
    assert set(u["T1_plus_key_state"]) == {"missing"} and set(u["check"]) == {"n/a"}
    assert "no site deep enough" in u["reason"].iloc[0]
    back = pd.read_parquet(tmp_path / "st.parquet")
    assert back["over_three_quarters"].dtype == "boolean"
    pd.testing.assert_frame_equal(back, df, check_dtype=False)
    tex = (tmp_path / "st.tex").read_text()
    line = next(ln for ln in tex.splitlines() if ln.startswith("G2G & "))
    assert "\\textbf{0.83}$^\\dagger$" in line and "100 [84, 100]" in line
    assert f"G2G FAIL ({A._text(TOP)} 0.83)" in tex and "SK n/a" in tex
    assert "three quarters" in tex and "no site deep enough" in tex


def test_stressor_check_passes_when_no_key_dominates(stressor_cells, tmp_path):
    files, plus, _ = stressor_cells
    keep = [f for f in files if f.stem.startswith("g") and f.stem != f"g1_{TOP}"]
    df = A.stressor_frame(keep)
    assert df.loc[df["key"] == TOP, "share_state"].iloc[0] == "n/a"
    assert set(df["check"]) == {"n/a"}                      # a key not evaluated
    f = tmp_path / "g1_top.parquet"
    write_cell(f, "G2G", 1, "heuristic", _ok(16),
               overrides={TOP: load_task_table("G2G")["tiers"][3][TOP]})
    df = A.stressor_frame(keep + [f])
    assert set(df["check"]) == {"pass"} and not df["over_three_quarters"].any()
    top = df.loc[df["share"].idxmax()]
    assert df["check_note"].iloc[0] == f"largest share: {top['key']} {top['share']:.2f}"


def test_stressor_values_are_the_ones_the_cells_ran_with(stressor_cells, tmp_path):
    """The T1 -> T3 values shown are the key cells' recorded overrides (a tier table edited
    after the cells ran does not relabel them)."""
    files, _, _ = stressor_cells
    keep = [f for f in files if f.stem.startswith("g") and f.stem != f"g1_{TOP}"]
    f = tmp_path / "g1_top.parquet"
    write_cell(f, "G2G", 1, "heuristic", _ok(15), overrides={TOP: 999})
    r = A.stressor_frame(keep + [f]).set_index("key").loc[TOP]
    assert json.loads(r["high_value"]) == 999
    assert json.loads(r["low_value"]) == load_task_table("G2G")["tiers"][1][TOP]


def test_a_key_that_cannot_be_applied_alone(stressor_cells, tmp_path):
    """A Tier-1 cell the task cannot build with its override (recorded ``tier_conflict``):
    its share is n/a with a double dagger, and the check is made on the other keys."""
    files, _, _ = stressor_cells
    keep = [f for f in files if f.stem.startswith("g") and f.stem != f"g1_{TOP}"]
    f = tmp_path / "g1_top.parquet"
    write_cell(f, "G2G", 1, "heuristic", [], applicable=False,
               overrides={TOP: load_task_table("G2G")["tiers"][3][TOP]},
               extra={"tier_conflict": True,
                      "reason": f"G2G tier 1 with {TOP} = 99: cannot build it"})
    df = A.stressor_table(keep + [f], tmp_path / "c.tex")
    r = df.set_index("key").loc[TOP]
    assert r["share_state"] == "conflict" and r["T1_plus_key_state"] == "n/a"
    assert set(df["check"]) == {"pass"}
    assert df["check_note"].iloc[0].endswith(f"; cannot be applied alone: {TOP}")
    tex = (tmp_path / "c.tex").read_text()
    assert "n/a$^\\ddagger$" in tex and "cannot build it" in tex


# ------------------------------------------------------------------------------ overrides

@pytest.fixture(scope="module")
def grid_file(tmp_path_factory):
    from oneocean.io import write_npz_atomic
    from oneocean.testing import make_test_grid

    f = tmp_path_factory.mktemp("grid") / "grid.npz"
    write_npz_atomic(f, make_test_grid(nt=5, nz=3, ny=30, nx=40, dt_s=3600.0))
    return f


def test_tier_override_changes_exactly_one_key(grid_file, tmp_path):
    from oneocean.tasks import Cell, rollout_to_file

    table = load_task_table("G2G")["tiers"]
    key, other = G_KEYS[-1], G_KEYS[0]
    out = tmp_path / "g2g_t1_key.parquet"
    rollout_to_file(grid_file, out, "G2G", 1, "heuristic", 3, 7, "6dof",
                    tier_overrides={key: table[3][key]})
    meta = read_metrics_meta(out)
    assert meta["tier_overrides"] == {key: table[3][key]}
    diff = {k for k in set(table[1]) | set(meta["tier_params"])
            if meta["tier_params"].get(k) != table[1].get(k)}
    assert diff == {key}
    assert meta["tier"] == 1 and "info" not in meta
    # read back as an ablation cell of its own, never the ladder's Tier-1 cell
    _, c = read_cell(out)
    assert c["ablation"] and c["tier_overrides"] == meta["tier_overrides"]
    assert C.load_cell_frames([out])["condition"].iloc[0] == f"set-{key}"
    # the same on the Cell itself; the tier table is left as it was
    cell = Cell(str(grid_file), "G2G", 3, tier_overrides={other: table[1][other]})
    assert cell.tier_params == {**table[3], other: table[1][other]}
    assert cell.params[other] == table[1][other]
    assert load_task_table("G2G")["tiers"][3] == table[3]
    # an information level is recorded the same way
    info = tmp_path / "g2g_t1_info.parquet"
    rollout_to_file(grid_file, info, "G2G", 1, "heuristic", 3, 7, "6dof", info="true_current")
    assert read_metrics_meta(info)["info"] == "true_current"
    assert C.load_cell_frames([info])["condition"].iloc[0] == "info-true_current"


def test_an_override_the_task_cannot_build_is_an_na_cell(grid_file, tmp_path):
    """More leaks than the pipeline holds: the cell is written, n/a with the task's reason and
    ``tier_conflict``; never a crash. Without overrides the same error stays an error."""
    from oneocean.tasks import rollout_to_file

    out = tmp_path / "pi.parquet"
    rollout_to_file(grid_file, out, "PI", 1, "heuristic", 2, 7, "6dof",
                    tier_overrides={"n_leaks": 50})
    meta = read_metrics_meta(out)
    assert not meta["applicable"] and meta["tier_conflict"] is True
    assert meta["reason"].startswith("PI tier 1 with n_leaks = 50: ") and "\n" not in meta["reason"]
    assert len(pd.read_parquet(out)) == 0
    with pytest.raises(ConfigError, match="information level"):
        rollout_to_file(grid_file, out, "PI", 1, "heuristic", 2, 7, "6dof",
                        tier_overrides={"n_leaks": 50}, info="psychic")


@pytest.mark.parametrize("overrides, named", [
    ({"goal_radiu_m": 5.0}, "'goal_radiu_m'"),
    ({G_KEYS[0]: 5.0, "fish_count": 3}, "'fish_count'"),
    ([G_KEYS[0]], "mapping"),
])
def test_a_bad_override_is_a_one_line_error(grid_file, overrides, named):
    from oneocean.tasks import run_cell

    with pytest.raises(ConfigError, match=named) as ei:
        run_cell(str(grid_file), "G2G", 1, "heuristic", episodes=2, tier_overrides=overrides)
    msg = str(ei.value)
    assert "\n" not in msg and "G2G" in msg and len(msg) < 300


# ------------------------------------------------------------------------------ config

def test_config_keys_of_the_ablations():
    cfg = load_config(REPO / "config" / "config.yaml")
    assert cfg["ablations"] == {"info": {"tier": 3, "levels": ["true_current", "true_position",
                                                             "true_target"]},
                                "stressors": {"episodes": None}}
    for override, named in (({"stressors": {"episodes": 0}}, "ablations.stressors.episodes"),
                            ({"info": {"levels": ["sensors"]}}, "ablations.info.levels"),
                            ({"stressor": {}}, "ablations.stressor")):
        with pytest.raises(ConfigError, match=named.replace(".", r"\.")) as ei:
            load_config(REPO / "config" / "config.yaml", overrides={"ablations": override})
        assert "\n" not in str(ei.value)

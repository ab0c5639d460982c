"""A cell run in shards of episodes (rollouts.shard_episodes / shard_minutes) and merged is
the whole cell's file byte for byte; the workflow shards only when a key asks for it, and a
runtime budget gives each task as many episodes per job as its measured cost allows."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from oneocean.errors import ConfigError
from oneocean.io import sha256_file, write_npz_atomic
from oneocean.tasks import merge_shards, rollout_to_file, shard_episodes_for, shard_ranges
from oneocean.testing import make_test_grid

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def grid_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("grid") / "grid.npz"
    write_npz_atomic(path, make_test_grid())
    return path


def test_shard_ranges():
    assert shard_ranges(7, None) == [(0, 7)]
    assert shard_ranges(7, 7) == shard_ranges(7, 50) == [(0, 7)]
    assert shard_ranges(7, 3) == [(0, 3), (3, 6), (6, 7)]
    with pytest.raises(ConfigError, match="rollouts.shard_episodes"):
        shard_ranges(7, 0)


def test_shard_episodes_for_a_runtime_budget():
    # 10 minutes for 12 cells at 2.5 s per episode and cell: 600 / 30 = 20 episodes
    assert shard_episodes_for(10, 2.5, 12) == 20
    assert shard_episodes_for(10, 2.6, 12) == 19          # floor: the budget is a ceiling
    assert shard_episodes_for(0.01, 100.0, 12) == 1       # never less than one episode
    with pytest.raises(ConfigError, match="rollouts.shard_minutes"):
        shard_episodes_for(0, 1.0, 1)


# SK Tier 3 keeps the candidates in its current band (a shard re-checks the whole cell's);
# G2G Tier 1 with the heuristic draws sensor errors (streams keyed by the cell's episode);
# PI's plume field has the cell's shape (its cell_constants), not the shard's
@pytest.mark.parametrize("task, tier, method", [("SK", 3, "heuristic"),
                                                ("G2G", 1, "heuristic"),
                                                ("PI", 2, "heuristic")])
def test_shards_merge_to_the_whole_cell_byte_for_byte(tmp_path, grid_path, task, tier,
                                                      method):
    episodes, seed = 7, 11
    whole = tmp_path / "whole.parquet"
    rollout_to_file(grid_path, whole, task, tier, method, episodes, seed, "6dof")
    for per in (3, 4):
        parts = []
        for a, b in shard_ranges(episodes, per):
            part = tmp_path / f"{per}" / f"cell.ep{a}-{b}.parquet"
            entry = rollout_to_file(grid_path, part, task, tier, method, episodes, seed,
                                    "6dof", shard=(a, b))
            assert entry["rows"] == b - a and entry["shard"] == [a, b]
            parts.append(part)
        merged = tmp_path / f"merged{per}.parquet"
        merge_shards(parts[::-1], merged)      # any order: merged in episode order
        assert sha256_file(merged) == sha256_file(whole)


def test_merge_refuses_a_gap_or_another_cell(tmp_path, grid_path):
    parts = {}
    for (a, b) in [(0, 2), (2, 4)]:
        parts[a] = tmp_path / f"ep{a}.parquet"
        rollout_to_file(grid_path, parts[a], "SK", 1, "heuristic", 4, 11, "6dof",
                        shard=(a, b))
    with pytest.raises(ConfigError, match="shards end at episode 2"):
        merge_shards([parts[0]], tmp_path / "m.parquet")
    other = tmp_path / "other.parquet"
    rollout_to_file(grid_path, other, "SK", 1, "heuristic", 4, 12, "6dof", shard=(2, 4))
    with pytest.raises(ConfigError, match="another cell"):
        merge_shards([parts[0], other], tmp_path / "m.parquet")
    with pytest.raises(ConfigError, match="not a range of episodes"):
        rollout_to_file(grid_path, other, "SK", 1, "heuristic", 4, 11, "6dof", shard=(3, 9))


def _dry_run(tmp_path, config):
    import yaml

    tmp_path.mkdir(parents=True)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump(config))
    out = subprocess.run([sys.executable, "-m", "snakemake", "-n", "--snakefile",
                          str(REPO / "Snakefile"), "--directory", str(tmp_path),
                          "--configfile", str(REPO / "config" / "config.yaml"), str(cfg),
                          "--", "paper_tables"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    stats = out.stdout.split("Job stats:")[-1]
    return {ln.split()[0]: int(ln.split()[1]) for ln in stats.splitlines()
            if len(ln.split()) == 2 and ln.split()[1].isdigit()}, out.stdout


def test_workflow_shards_only_when_asked(tmp_path):
    sys.path.insert(0, str(REPO / "tests"))
    from workflow_helpers import SMALL_CONFIG

    plain, _ = _dry_run(tmp_path / "plain", SMALL_CONFIG)
    assert plain["rollout_task"] == 2
    assert "rollout_task_shard" not in plain and "merge_rollout_shards" not in plain
    cfg = {**SMALL_CONFIG, "rollouts": {**SMALL_CONFIG["rollouts"], "shard_episodes": 3}}
    sharded, text = _dry_run(tmp_path / "sharded", cfg)
    assert "rollout_task" not in sharded
    assert sharded["rollout_task_shard"] == 4 and sharded["merge_rollout_shards"] == 2
    assert "results/rollouts/ci_coast/public/G2G/shards/ep3-4/tier1/heuristic.parquet" in text
    # the rest of the DAG is the same
    rest = {k: v for k, v in sharded.items()
            if k not in ("rollout_task_shard", "merge_rollout_shards", "total")}
    assert rest == {k: v for k, v in plain.items() if k not in ("rollout_task", "total")}


def test_workflow_shards_to_a_runtime_budget(tmp_path):
    """rollouts.shard_minutes: each task shards by its own measured cost (the cost table
    beside the rules), a generous budget shards nothing, a tiny one gives one-episode jobs."""
    import yaml

    sys.path.insert(0, str(REPO / "tests"))
    from workflow_helpers import SMALL_CONFIG

    seconds = yaml.safe_load((REPO / "workflow" / "resources" / "rollout_seconds.yaml")
                             .read_text())["seconds"]
    assert set(seconds) >= {"G2G", "SK", "RF", "DPT", "AS", "PI", "FT", "SPC", "UPL", "FH"}
    assert all(v > 0 for v in seconds.values())

    def run(name, minutes):
        cfg = {**SMALL_CONFIG, "rollouts": {**SMALL_CONFIG["rollouts"], "episodes": 12,
                                             "shard_minutes": minutes}}
        return _dry_run(tmp_path / name, cfg)

    assert "rollout_task_shard" not in run("generous", 1e4)[0]
    tiny, text = run("tiny", 1e-4)              # 12 one-episode jobs for each of 2 tasks
    assert tiny["rollout_task_shard"] == 24 and tiny["merge_rollout_shards"] == 2
    assert "rollout_task" not in tiny
    # the cells one job runs (methods x tiers and the ablation cells, bc's apart)
    n_cells = len(set(re.findall(r"results/rollouts/ci_coast/public/G2G/shards/ep0-1/\S+?"
                                 r"\.parquet", text)))
    assert n_cells >= 3
    # a budget between the two tasks' costs: the cheaper task in one job, the dearer in shards
    lo, hi = sorted((seconds["G2G"], seconds["FT"]))
    assert lo < hi
    minutes = 12 * n_cells * (lo + hi) / 2 / 60  # the cheap task's 12 episodes fit, not the dear
    mid, _ = run("mid", minutes)
    assert mid["rollout_task"] == 1 and mid["merge_rollout_shards"] == 1
    per = shard_episodes_for(minutes, hi, n_cells)
    assert mid["rollout_task_shard"] == len(shard_ranges(12, per)) > 1

"""The fast tier's workflow run: the Snakefile on the small config of ``.test/config/``
(a synthetic coast, SK Tier 1, three heuristic episodes), from the product to the
task-success table. The whole DAG runs in the slow tier (tests/test_workflow.py)."""

import json

import pandas as pd
import pytest
import yaml

from workflow_helpers import REPO, run_workflow

CONFIG = yaml.safe_load((REPO / ".test" / "config" / "config.yaml").read_text())
REGION = CONFIG["region"]["name"]
TABLE = f"results/tables/{REGION}/task_success_by_tier"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    wd = tmp_path_factory.mktemp("small")
    run_workflow(wd, targets=(f"{TABLE}.tex",), config=CONFIG)
    return wd


def test_table_states_its_cell(run):
    """The table's SK Tier-1 row is the cell's own success rate over its 3 episodes, with a
    Wilson interval around it."""
    cell = pd.read_parquet(
        run / f"results/rollouts/{REGION}/public/SK/tier1/heuristic.parquet")
    assert len(cell) == 3
    assert cell["seed"].nunique() == 1 and int(cell["seed"].iloc[0]) == 1000
    table = pd.read_parquet(run / f"{TABLE}.parquet")
    row = table[(table.task == "SK") & (table.tier == 1) & (table.method == "heuristic")]
    assert len(row) == 1
    sr = float(row["sr"].iloc[0])
    assert sr == pytest.approx(100.0 * cell["success"].mean())
    assert float(row["lo"].iloc[0]) <= sr <= float(row["hi"].iloc[0])
    assert int(row["n"].iloc[0]) == 3
    tex = (run / f"{TABLE}.tex").read_text()
    assert "SK" in tex


def test_table_provenance_hashes_its_cell(run):
    """The table's provenance names the cell it read, with the cell file's own sha256."""
    import hashlib

    prov = json.loads((run / f"results/provenance/tables/{REGION}/task_success_by_tier.json")
                      .read_text())
    rel = f"results/rollouts/{REGION}/public/SK/tier1/heuristic.parquet"
    (entry,) = [x for x in prov["inputs"] if x["path"] == rel]
    assert entry["sha256"] == hashlib.sha256((run / rel).read_bytes()).hexdigest()

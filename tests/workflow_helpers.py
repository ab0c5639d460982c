"""Run the Snakemake workflow through its Python API in a scratch working directory."""

from __future__ import annotations

from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]

#: A small synthetic region so the whole DAG runs in seconds.
SMALL_CONFIG = {
    "region": {
        "name": "ci_coast",
        "bbox": {"west": -4.50, "east": -4.38, "south": 50.20, "north": 50.30},
        "time": {"start": "2025-01-01T00:00:00", "end": "2025-01-01T12:00:00"},
        "max_depth_m": 40.0,
    },
    "synthetic": {"resolution_deg": 0.004, "time_step_hours": 2.0,
                  "depths_m": [0.5, 10.0, 40.0]},
    "variants": {
        "tiny": {"extent_fraction": 0.5, "resolution_deg": 0.008, "hours": 6, "max_depth_m": 10},
        "scene": {"extent_fraction": 0.8, "resolution_deg": 0.004, "hours": 8, "max_depth_m": 40},
        "public": {"extent_fraction": 1.0, "resolution_deg": 0.004, "hours": 12,
                   "max_depth_m": 40},
    },
    "rollouts": {"variant": "public", "tasks": ["G2G", "FT"], "tiers": [1, 3],
                 "methods": ["heuristic", "bc"], "episodes": 4, "seed": 1000,
                 "dynamics": "6dof",
                 "team_sweep": {"task": "SPC", "tier": 1, "method": "heuristic",
                                "sizes": [2, 3]}},
    "bc": {"train_seeds": [100], "episodes": 3, "stride": 5, "max_rows": 300,
           "hidden": [16, 16], "epochs": 3},
    "planning": {"tasks": ["SPC"], "tier": 1, "episodes": 3, "cost_episodes": 2,
                 "methods": ["heuristic", "bc"]},
    "snapshots": {"tasks": ["SPC", "FT"], "tier": 1},
    # the stressor table's cells (2 per tier key) with few episodes each
    "ablations": {"stressors": {"episodes": 2}},
    # the scene backend: two small scenes, one task whose kernel the rollouts compile
    "scenes": {"tasks": ["G2G"], "tiers": [3], "methods": ["heuristic"], "episodes": 2,
               "compare": "open_water",
               "media": {"keyframes": 2, "width": 96, "height": 72, "fps": 5},
               "list": [{"name": "open_water", "kind": "open_water", "size_m": 360,
                         "resolution_m": 8},
                        {"name": "pier_harbor", "kind": "pier_harbor", "size_m": 360,
                         "resolution_m": 8, "depth_m": 20}]},
}


def run_workflow(workdir: Path, targets=("paper_tables",), config: dict | None = None,
                 cores: int = 2, forcerun=()) -> None:
    """Execute ``targets`` with the repo's Snakefile in ``workdir`` (outputs land there)."""
    from snakemake.api import SnakemakeApi
    from snakemake.settings.types import (ConfigSettings, DAGSettings, ExecutionSettings,
                                          OutputSettings, ResourceSettings)

    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    cfg_path = workdir / "test_config.yaml"
    cfg_path.write_text(yaml.safe_dump(config if config is not None else SMALL_CONFIG))
    with SnakemakeApi(OutputSettings(quiet={"all"} if False else None, show_failed_logs=True)) as api:
        wf = api.workflow(
            resource_settings=ResourceSettings(cores=cores),
            config_settings=ConfigSettings(configfiles=[REPO / "config" / "config.yaml",
                                                        cfg_path]),
            snakefile=REPO / "Snakefile",
            workdir=workdir,
        )
        dag = wf.dag(DAGSettings(targets=set(targets), forcerun=set(forcerun)))
        dag.execute_workflow(executor="local", execution_settings=ExecutionSettings(lock=False))


def need_tex(program: str = "pdflatex") -> None:
    """Skip the calling test where ``program`` (TeX) is not installed, except in CI
    (``ONEOCEAN_REQUIRE_TEX=1``, set by .ci/run after it installs Debian's TeX packages),
    where a missing TeX fails the test."""
    import os
    import shutil

    import pytest

    if shutil.which(program) is None:
        if os.environ.get("ONEOCEAN_REQUIRE_TEX") == "1":
            pytest.fail(f"{program} not installed, but ONEOCEAN_REQUIRE_TEX=1")
        pytest.skip(f"{program} not installed")

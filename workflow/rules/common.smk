# Config validation, vocabularies, input functions and code hashes (no numerics here).
import hashlib
import importlib.util
import re
import sys
from pathlib import Path

from oneocean.codeversion import task_code, tasks_code
from oneocean.config import llm_method, validate_config
from oneocean.errors import ConfigError
from oneocean.registry import method_names, task_ids
from oneocean.vocab import TIERS, VARIANTS

try:
    # imports config["plugins"] first (they may register tasks and methods), then validates
    # against the packaged schema whose task/method enums come from oneocean.registry
    validate_config(config)
except ConfigError as _err:
    raise WorkflowError(str(_err)) from None

REGION = config["region"]["name"]


wildcard_constraints:
    region=r"[A-Za-z0-9_-]+",
    variant="|".join(VARIANTS),
    task="|".join(map(re.escape, task_ids())),
    tier="|".join(map(str, TIERS)),
    method="|".join(map(re.escape, method_names())),


def code_version(*modules):
    """sha256 of the source of oneocean modules/packages a rule depends on, their ``.py`` files
    and data tables (``.yaml``) (a params value, so that editing the code or a table such as a
    task's tier table reruns the rule)."""
    h = hashlib.sha256()
    for mod in modules:
        spec = importlib.util.find_spec(mod)
        if spec is None:
            raise WorkflowError(f"code_version: module {mod} not found")
        if spec.submodule_search_locations:
            files = sorted(f for d in spec.submodule_search_locations for pat in ("*.py", "*.yaml")
                           for f in Path(d).rglob(pat))
        else:
            files = [Path(spec.origin)]
        for f in files:
            h.update(f.name.encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def config_section(*keys):
    return {k: config[k] for k in keys}


def product_targets():
    return expand(
        "results/product/{region}/{variant}/{name}",
        region=REGION,
        variant=VARIANTS,
        name=["product.nc", "metadata.json"],
    )


def export_targets():
    return expand(
        "results/exports/{region}/{variant}/{name}.npz",
        region=REGION,
        variant=VARIANTS,
        name=["grid", "temporal"],
    )


def figure_targets():
    return expand(
        "results/figures/{region}/{variant}/current_field.png",
        region=REGION,
        variant=VARIANTS,
    )


def rollout_targets():
    r = config["rollouts"]
    return expand(
        "results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}.parquet",
        region=REGION,
        variant=r["variant"],
        task=r["tasks"],
        tier=r["tiers"],
        method=r["methods"],
    )


def currents_off_targets():
    r = config["rollouts"]
    off = r["currents_off"]
    return expand(
        "results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_currents-off.parquet",
        region=REGION,
        variant=r["variant"],
        task=r["tasks"],
        tier=[t for t in off["tiers"] if t in r["tiers"]],
        method=[m for m in off["methods"] if m in r["methods"]],
    )


def forcing_targets():
    """The currents ablation's doubled-gain and tide cells."""
    r = config["rollouts"]
    fa = r["forcing_ablation"]
    return expand(
        "results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_{forcing}.parquet",
        region=REGION,
        variant=r["variant"],
        task=r["tasks"],
        tier=[t for t in fa["tiers"] if t in r["tiers"]],
        method=[m for m in fa["methods"] if m in r["methods"]],
        forcing=["gain", "tide"],
    )


def team_targets():
    """Fig. 7's team-size sweep cells."""
    r = config["rollouts"]
    ts = r["team_sweep"]
    return expand(
        "results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_n{n}.parquet",
        region=REGION,
        variant=r["variant"],
        task=ts["task"],
        tier=ts["tier"],
        method=ts["method"],
        n=ts["sizes"],
    )


def _prov(paths):
    return [
        p.replace("results/", "results/provenance/", 1).replace(".parquet", ".json")
        for p in paths
    ]


#: The paper's tables and figures of this region (beside the ladder and planning tables).
PAPER_TABLES = [
    f"results/tables/{REGION}/{name}.tex"
    for name in ("dataset_variants", "task_ladder", "headline", "task_success_by_tier",
                 "difficulty_heuristic", "currents_ablation")
]
PAPER_FIGURES = [
    f"results/figures/{REGION}/{name}.png"
    for name in ("pollution_species", "ladder", "team_sweep")
]


def provenance_targets():
    """Every job's provenance file in the paper DAG (collected into
    results/manifest/<region>.json)."""
    stages = [
        f"results/provenance/fetch/{REGION}/currents.json",
        f"results/provenance/fetch/{REGION}/bathymetry.json",
    ]
    for v in VARIANTS:
        stages += [
            f"results/provenance/product/{REGION}/{v}.json",
            f"results/provenance/exports/{REGION}/{v}/grid.json",
            f"results/provenance/exports/{REGION}/{v}/temporal.json",
            f"results/provenance/figures/{REGION}/{v}/current_field.json",
        ]
    stages += [p.replace("results/tables/", "results/provenance/tables/").replace(".tex", ".json")
               for p in PAPER_TABLES]
    stages += [p.replace("results/figures/", "results/provenance/figures/").replace(".png", ".json")
               for p in PAPER_FIGURES]
    stages += _prov(forcing_targets() + team_targets())
    stages += [
        p.replace("results/rollouts/", "results/provenance/rollouts/").replace(
            ".parquet", ".json"
        )
        for p in rollout_targets() + currents_off_targets()
    ]
    if "bc" in config["rollouts"]["methods"] or "bc" in config["planning"]["methods"]:
        v = config["rollouts"]["variant"]
        stages += [f"results/provenance/bc/{REGION}/{v}/dataset.json",
                   f"results/provenance/bc/{REGION}/{v}/weights.json"]
    stages += [
        p.replace("results/planning/", "results/provenance/planning/").replace(
            ".parquet", ".json"
        )
        for p in planning_targets()
    ]
    stages.append(f"results/provenance/tables/{REGION}/planning.json")
    stages.append(f"results/provenance/tables/{REGION}/ladder.json")

    return stages

# Config validation, vocabularies, input functions and code hashes (no numerics here).
import hashlib
import importlib.util
import re
import sys
from pathlib import Path

from oneocean.reporting.ablations import HIGH_TIER, LOW_TIER, stressor_cells
from oneocean.pipeline.codeversion import task_code, tasks_code
from oneocean.config import llm_method, validate_config
from oneocean.errors import ConfigError
from oneocean.registry import method_names, task_ids
from oneocean.vocab import TIERS, VARIANTS
from oneocean.product.zarrio import export_filename, is_zarr, product_filename

try:
    # imports config["plugins"] first (they may register tasks and methods), then validates
    # against the packaged schema whose task/method enums come from oneocean.registry
    validate_config(config)
except ConfigError as _err:
    raise WorkflowError(str(_err)) from None

REGION = config["region"]["name"]

# Each rule's software (`snakemake --sdm conda`), pinned in workflow/envs/ (paths relative to
# the rule files).
PY_ENV = "../envs/oneocean.yaml"
LATEX_ENV = "../envs/latex.yaml"


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


def workflow_source_version():
    """sha256 of the workflow's Snakefiles and rule files (Fig. 2 is their rule graph)."""
    h = hashlib.sha256()
    for f in sorted([Path(workflow.main_snakefile).resolve(), *Path(workflow.current_basedir)
                     .parent.glob("Snakefile"), *Path(workflow.current_basedir).glob("*.smk")]):
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
        name=[PRODUCT_NAME, "metadata.json"],
    )


def export_targets():
    return expand(
        "results/exports/{region}/{variant}/{name}",
        region=REGION,
        variant=VARIANTS,
        name=[export_filename(k, config["exports"]["format"]) for k in ("grid", "temporal")],
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


def replicate_targets():
    """The ladder's cells on the replicate seeds (rollouts.replicate)."""
    r = config["rollouts"]
    rep = r.get("replicate") or {}
    return expand(
        "results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_seed{seed}.parquet",
        region=REGION,
        variant=r["variant"],
        task=r["tasks"],
        tier=r["tiers"],
        method=[m for m in rep.get("methods", []) if m in r["methods"]],
        seed=rep.get("seeds", []),
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


def ablation_targets():
    """Every task's ablation cells, made by the rollout_ablation_<task> rules: the information
    ablation and the stressor cells."""
    v = config["rollouts"]["variant"]
    return [p.format(region=REGION, variant=v) for t in config["rollouts"]["tasks"]
            for p in _ablation_files(t, ablation_cells(t), "parquet")]


#: The paper's tables and figures of this region (beside the ladder and planning tables).
PAPER_TABLES = [
    f"results/tables/{REGION}/{name}.tex"
    for name in ("systems", "dataset_variants", "task_ladder", "headline", "task_success_by_tier",
                 "difficulty_heuristic", "currents_ablation", "information_ablation",
                 "tier_stressors")
]
PAPER_FIGURES = [
    f"results/figures/{REGION}/{name}.png"
    for name in ("overview_registry", "overview_workflow", "pollution_species", "snapshots",
                 "ladder", "team_sweep")
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
    stages += _prov(forcing_targets() + team_targets() + ablation_targets()
                    + replicate_targets())
    r = config["rollouts"]
    kernel_tasks = dict.fromkeys([*r["tasks"], r["team_sweep"]["task"],
                                  *config["planning"]["tasks"], *config["snapshots"]["tasks"]])
    stages += [f"results/provenance/kernels/{REGION}/{r['variant']}/{t}.json"
               for t in kernel_tasks]
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
    stages += scene_provenance()   # workflow/rules/scenes.smk

    return stages


# ---- input functions and params of rules/rollouts.smk
# the code a cell of one task depends on (oneocean.pipeline.codeversion): editing one task's module,
# heuristic or tier table reruns only its cells; hashed once per task and parse
def rollout_code(wc):
    return task_code(wc.task)


def _run(currents=True, forcing=None, n_agents=None, seed=None):
    """The run settings of a cell: the config's, or an ablation's forcing ("gain": the
    forcing ablation's gain on the data currents; "tide": the data plus its tide term), or a
    replicate seed's."""
    r = config["rollouts"]
    run = {**{k: r[k] for k in ("episodes", "seed", "dynamics", "current_gain", "tide")},
           "currents": currents, "n_agents": n_agents}
    if r["backend"] != "core":   # (the core's run records stay as they were)
        run.update(backend=r["backend"], scene=r["scene"],
                   physics_step_s=config["scenes"]["physics_step_s"])
    if seed is not None:
        run["seed"] = int(seed)
    fa = r["forcing_ablation"]
    if forcing == "gain":
        run["current_gain"] = fa["gain"] * r["current_gain"]
    elif forcing == "tide":
        run["tide"] = dict(fa["tide"])
    return run


def ladder_scene(wc):
    """The scene file the ladder's cells run in when rollouts.backend is mujoco, else none."""
    r = config["rollouts"]
    if r["backend"] != "mujoco":
        return []
    return [f"results/scenes/{wc.region}/{wc.variant}/{r['scene']}/scene.json"]


def task_cells(learned):
    """The cells one job runs for one task: every configured (method, tier), then the
    currents-off and forcing-ablation cells; ``learned``: method bc's cells (they wait for
    its weights), else every other method's. The same list for every task."""
    r = config["rollouts"]
    off, fa = r["currents_off"], r["forcing_ablation"]

    def keep(methods):
        return [m for m in methods if m in r["methods"] and (m == "bc") == learned]

    cells = [(m, t, "", _run()) for m in keep(r["methods"]) for t in r["tiers"]]
    cells += [(m, t, "_currents-off", _run(currents=False))
              for m in keep(off["methods"]) for t in off["tiers"] if t in r["tiers"]]
    cells += [(m, t, f"_{f}", _run(forcing=f)) for f in ("gain", "tide")
              for m in keep(fa["methods"]) for t in fa["tiers"] if t in r["tiers"]]
    rep = r.get("replicate") or {}
    cells += [(m, t, f"_seed{s}", _run(seed=s)) for s in rep.get("seeds", [])
              for m in keep(rep.get("methods", [])) for t in r["tiers"]]
    return [{"method": m, "tier": t, "suffix": sfx, "run": run} for m, t, sfx, run in cells]


def _cell_files(cells, kind):
    """Output paths of ``cells`` (region, variant and task stay wildcards)."""
    if kind == "parquet":
        pat = "results/rollouts/{{region}}/{{variant}}/{{task}}/tier{tier}/{method}{suffix}.parquet"
    else:
        pat = ("results/provenance/rollouts/{{region}}/{{variant}}/{{task}}/tier{tier}/"
               "{method}{suffix}.json")
    return [pat.format(**c) for c in cells]


def _cell_entry(method, tier, run, wildcards, code):
    """One cell of a batched rollout job: what to run, and its own provenance record's
    wildcards and params (``params.run`` is the run the script executes)."""
    return {"method": method, "tier": int(tier), "wildcards": wildcards,
            "params": {"code": code, "run": run}}


def _cell_params(cells):
    """Per-cell entries of a task's job (:func:`_cell_entry`), with the task's code hash."""

    def fn(wc):
        code = rollout_code(wc)
        return [_cell_entry(c["method"], c["tier"], c["run"],
                            {"method": c["method"], "tier": str(c["tier"])}, code)
                for c in cells]

    return fn


#: The ablations' method (oneocean.reporting.ablations: the heuristic).
ABLATION_METHOD = "heuristic"


def _ablation_run(info=None, tier_overrides=None, episodes=None):
    """An ablation cell's run: the config's (:func:`_run`) with an information level or tier
    overrides, and its own episode count."""
    run = _run()
    if episodes is not None:
        run["episodes"] = int(episodes)
    return {**run, "info": info, "tier_overrides": tier_overrides}


def stressor_episodes():
    """Episodes per stressor cell (ablations.stressors.episodes; null: rollouts.episodes)."""
    e = config["ablations"]["stressors"]["episodes"]
    return int(config["rollouts"]["episodes"] if e is None else e)


def ablation_cells(task):
    """The ablation cells one job runs for ``task`` (its rollout_ablation_<task> rule), the
    information levels at ablations.info.tier (if it is in rollouts.tiers), then the stressor
    cells (oneocean.reporting.ablations.stressor_cells: per tier key, Tier 1 with the key at its Tier-3
    value and Tier 3 with it at its Tier-1 value; if both tiers are in rollouts.tiers)."""
    r, a = config["rollouts"], config["ablations"]
    m = ABLATION_METHOD
    cells = []
    tier = int(a["info"]["tier"])
    if tier in r["tiers"]:
        cells += [{"method": m, "tier": tier, "suffix": f"_info-{lvl}",
                   "wildcards": {"info": lvl}, "run": _ablation_run(info=lvl)}
                  for lvl in a["info"]["levels"]]
    if LOW_TIER in r["tiers"] and HIGH_TIER in r["tiers"]:
        n = stressor_episodes()
        cells += [{"method": m, "tier": c["tier"],
                   "suffix": f"_set-{c['key']}-T{c['from_tier']}",
                   "wildcards": {"set": c["key"], "from_tier": str(c["from_tier"])},
                   "run": _ablation_run(tier_overrides=c["overrides"], episodes=n)}
                  for c in stressor_cells(task, LOW_TIER, HIGH_TIER)]
    return cells


def _ablation_files(task, cells, kind):
    """Output paths of one task's ablation cells (region and variant stay wildcards)."""
    return [p.replace("{task}", task) for p in _cell_files(cells, kind)]


def ablation_rule_name(task):
    """The name of the rule that runs ``task``'s ablation cells (one per task, whose tier
    keys are its own)."""
    safe = re.sub(r"\W", "_", task)
    return f"rollout_ablation_{safe}"


def _ablation_params(task, cells):
    """Per-cell entries of a task's ablation job (:func:`_cell_entry`)."""
    code = task_code(task)
    return [_cell_entry(c["method"], c["tier"], c["run"],
                        {"task": task, "method": c["method"], "tier": str(c["tier"]),
                         **c["wildcards"]}, code)
            for c in cells]


def information_table_cells():
    """The information-ablation table's cells: per task at ablations.info.tier, the
    heuristic's ladder cell, its information-level cells, its currents-off cell and the
    oracle's cell (those the config runs)."""
    r, tier = config["rollouts"], int(config["ablations"]["info"]["tier"])
    have = set(rollout_targets() + currents_off_targets())
    cells = ablation_targets()
    out = []
    for t in r["tasks"]:
        d = f"results/rollouts/{REGION}/{r['variant']}/{t}/tier{tier}"
        out += [p for p in (f"{d}/{ABLATION_METHOD}.parquet", f"{d}/oracle.parquet",
                            f"{d}/{ABLATION_METHOD}_currents-off.parquet") if p in have]
        out += [p for p in cells if p.startswith(f"{d}/")
                and Path(p).name.startswith(f"{ABLATION_METHOD}_info-")]
    return out


def stressor_table_cells():
    """The stressor table's cells: per task the heuristic's Tier-1 and Tier-3 ladder cells
    and its stressor cells."""
    r = config["rollouts"]
    have = set(rollout_targets())
    cells = ablation_targets()
    out = []
    for t in r["tasks"]:
        d = f"results/rollouts/{REGION}/{r['variant']}/{t}"
        out += [p for p in (f"{d}/tier{LOW_TIER}/{ABLATION_METHOD}.parquet",
                            f"{d}/tier{HIGH_TIER}/{ABLATION_METHOD}.parquet") if p in have]
        out += [p for p in cells if p.startswith(f"{d}/")
                and Path(p).name.startswith(f"{ABLATION_METHOD}_set-")]
    return out


def bc_weights(wc):
    """Method bc's trained weights (the bc_train rule's output); no input for other methods."""
    return f"results/bc/{wc.region}/{wc.variant}/weights.npz" if wc.method == "bc" else []


def kernel_tiers():
    """Every tier a task kernel runs at in this config (rollouts, planning suite, team sweep,
    Fig. 5)."""
    r = config["rollouts"]
    return sorted({*r["tiers"], config["planning"]["tier"], r["team_sweep"]["tier"],
                   config["snapshots"]["tier"]})


def team_sizes():
    """Fig. 7's team sizes (one cell each in the rollout_team job)."""
    return [int(n) for n in config["rollouts"]["team_sweep"]["sizes"]]


def _team_params(wc):
    """Per-cell entries of the team-size sweep's job (:func:`_cell_entry`)."""
    code = rollout_code(wc)
    return [_cell_entry(wc.method, wc.tier, _run(n_agents=n), {"n": str(n)}, code)
            for n in team_sizes()]


# ---- input functions and params of rules/bc.smk
def bc_cells():
    """The (tasks, tiers) the network is trained on: every rollout cell's, plus the planning
    suite's when BC runs there."""
    r, p = config["rollouts"], config["planning"]
    tasks, tiers = list(r["tasks"]), list(r["tiers"])
    if "bc" in p["methods"]:
        tasks += [t for t in p["tasks"] if t not in tasks]
        tiers += [p["tier"]] if p["tier"] not in tiers else []
    return tasks, sorted(tiers)


# ---- input functions and params of rules/planning.smk
def planning_llm_methods():
    return [llm_method(m) for m in config["llm"]["models"]]


def planning_targets():
    p = config["planning"]
    return expand(
        "results/planning/{region}/{variant}/{task}/{method}.parquet",
        region=REGION,
        variant=config["rollouts"]["variant"],
        task=p["tasks"],
        method=list(p["methods"]) + planning_llm_methods(),
    )


def _planning_run(wc):
    p, r = config["planning"], config["rollouts"]
    return {"tier": p["tier"], "episodes": p["episodes"], "seed": r["seed"],
            "dynamics": r["dynamics"], "current_gain": p["current_gain"] * r["current_gain"]}


def _planning_llm_run(wc):
    """An LLM cell's run: the suite's, but for llm.episodes (null: the suite's episodes)."""
    run, n = _planning_run(wc), config["llm"].get("episodes")
    return run if n is None else {**run, "episodes": n}


# ---- input functions and params of rules/figures.smk
def _figure_io(name, caption):
    """A paper figure's outputs; the PNG goes into `snakemake --report` with ``caption``
    (workflow/report/<caption>.rst)."""
    return {
        "png": report(f"results/figures/{{region}}/{name}.png",
                      caption=f"../report/{caption}.rst", category="Figures"),
        "pdf": f"results/figures/{{region}}/{name}.pdf",
        "prov": f"results/provenance/figures/{{region}}/{name}.json",
    }


# ---- input functions and params of rules/tables.smk
def _table_rule_io(name, caption="table"):
    """A paper table's outputs; the LaTeX goes into `snakemake --report` with ``caption``
    (workflow/report/<caption>.rst)."""
    return {
        "tex": report(f"results/tables/{{region}}/{name}.tex",
                      caption=f"../report/{caption}.rst", category="Tables"),
        "parquet": f"results/tables/{{region}}/{name}.parquet",
        "prov": f"results/provenance/tables/{{region}}/{name}.json",
    }


# ---- input functions and params of rules/paper.smk
def paper_inputs():
    r = config["rollouts"]
    figs = [p.replace(".png", ".pdf") for p in PAPER_FIGURES]
    figs.append(f"results/figures/{REGION}/scene/current_field.pdf")
    if "bc" in r["methods"] or "bc" in config["planning"]["methods"]:
        figs.append(f"results/figures/{REGION}/{r['variant']}/bc_training.pdf")
    scene = ([f"results/tables/{REGION}/scene_backend.tex",
              f"results/tables/{REGION}/scene_vs_core.tex"] if config["scenes"]["enabled"] else [])
    return PAPER_TABLES + [f"results/tables/{REGION}/planning_performance.tex",
                           f"results/tables/{REGION}/planning_cost.tex"] + scene + figs


# ---- input functions and params of rules/rl.smk
def rl_episodes():
    """Episodes per PPO evaluation cell (rl.episodes; null: rollouts.episodes)."""
    e = config["rl"]["episodes"]
    return int(config["rollouts"]["episodes"] if e is None else e)


def rl_evaluation_seeds():
    """The seeds PPO never trains on: the evaluation seed and the replicate seeds."""
    r = config["rollouts"]
    return [int(r["seed"])] + [int(s) for s in (r.get("replicate") or {}).get("seeds", [])]


def rl_cell_targets(kind="parquet"):
    """The PPO cells (or their provenance records): every rl task at every rl.tiers_eval."""
    if not config["rl"]["enabled"]:
        return []
    d = "results/rollouts" if kind == "parquet" else "results/provenance/rollouts"
    ext = "parquet" if kind == "parquet" else "json"
    return expand(f"{d}/{{region}}/{{variant}}/{{task}}/tier{{tier}}/ppo.{ext}",
                  region=REGION, variant=config["rollouts"]["variant"],
                  task=config["rl"]["tasks"], tier=config["rl"]["tiers_eval"])


def rl_table_cells():
    """Table V over the RL tasks: the configured methods' ladder cells of those tasks and
    tiers, and the PPO cells."""
    rl = config["rl"]
    want = {(t, f"tier{k}") for t in rl["tasks"] for k in rl["tiers_eval"]}
    return [p for p in rollout_targets() if Path(p).parts[-3:-1] in want] + rl_cell_targets()


def rl_targets():
    """Everything rl_baselines builds (nothing when rl.enabled is false)."""
    if not config["rl"]["enabled"]:
        return []
    v = config["rollouts"]["variant"]
    return (expand("results/rl/{region}/{variant}/{task}/{name}", region=REGION, variant=v,
                   task=config["rl"]["tasks"], name=["policy.zip", "training_report.json"])
            + rl_cell_targets()
            + [f"results/tables/{REGION}/task_success_by_tier_rl.tex",
               f"results/figures/{REGION}/rl_learning_curves.png",
               f"results/manifest/{REGION}.rl.json"])


def rl_provenance():
    """The provenance records of this stage (its manifest's inputs)."""
    v = config["rollouts"]["variant"]
    return (expand("results/provenance/rl/{region}/{variant}/{task}/policy.json",
                   region=REGION, variant=v, task=config["rl"]["tasks"])
            + rl_cell_targets("prov")
            + [f"results/provenance/tables/{REGION}/task_success_by_tier_rl.json",
               f"results/provenance/figures/{REGION}/rl_learning_curves.json"])


def rl_run(wc):
    """What an evaluation cell runs: the rollouts' episodes, seed, dynamics and forcing
    (oneocean.methods.ppo.policy refuses a forcing the step API cannot apply)."""
    r = config["rollouts"]
    return {"episodes": rl_episodes(), "seed": int(r["seed"]), "dynamics": r["dynamics"],
            "current_gain": r["current_gain"], "tide": r["tide"], "backend": r["backend"]}

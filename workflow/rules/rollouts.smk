# Stage 4: core-backend rollouts. Each task's kernel is compiled once (compile_kernel); one
# job per task runs all its cells (rollout_task; bc's after training: rollout_task_bc), each
# cell's episodes batched inside one numba kernel call, one file per cell.
# With rollouts.shard_episodes or rollouts.shard_minutes, a task's non-learned cells run as
# one job per range of episodes (rollout_task_shard) and merge_rollout_shards writes the same
# cell files; the tasks that need no sharding keep rollout_task.

# Cluster resources (`--executor slurm`, profiles/slurm): runtime in minutes, mem_mb in MB,
# at least twice the figures results/benchmarks/ records for the default config on a 2-core
# machine (kernels: <= 285 s, 645 MB; a task's cells: <= 275 s, 690 MB; team sweep 115 s).
# Rule group "rollouts": many per-task jobs of a few minutes each; `--group-components
# rollouts=5` submits five of them as one cluster job.
localrules:
    table_ladder,


import math

import yaml

from oneocean.tasks import shard_episodes_for, shard_ranges


# Each task's episode kernel is compiled once, into numba's on-disk cache, before any job
# runs it: without this, every job that starts before the cache exists compiles the same
# kernel again (30-45 s each on a cold machine).
rule compile_kernel:
    conda:
        PY_ENV
    priority: 10
    input:
        grid=rules.export_grid.output.npz,
    output:
        record="results/kernels/{region}/{variant}/{task}.json",
        prov="results/provenance/kernels/{region}/{variant}/{task}.json",
    log:
        "logs/kernels/{region}/{variant}/{task}.log",
    benchmark:
        "results/benchmarks/kernels/{region}/{variant}/{task}.tsv"
    params:
        tiers=lambda wc: kernel_tiers(),
        dynamics=lambda wc: config["rollouts"]["dynamics"],
        code=rollout_code,
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    script:
        "../scripts/compile_kernel.py"


_BASE_CELLS = task_cells(learned=False)
_BC_CELLS = task_cells(learned=True)
# Measured cost of one episode of one cell per task (s), for rollouts.shard_minutes.
_ROLLOUT_SECONDS = yaml.safe_load(
    (Path(workflow.current_basedir).parent / "resources" / "rollout_seconds.yaml")
    .read_text())["seconds"]


def rollout_shards(task):
    """The episode ranges [a, b) a task's non-learned cells run in: one range (no sharding)
    unless rollouts.shard_episodes, or the episodes rollouts.shard_minutes allows at the
    task's measured cost per episode (workflow/resources/rollout_seconds.yaml), is smaller
    than rollouts.episodes."""
    r = config["rollouts"]
    per = r["shard_episodes"]
    if r.get("shard_minutes") is not None:
        fit = shard_episodes_for(r["shard_minutes"], _ROLLOUT_SECONDS.get(task, max(
            _ROLLOUT_SECONDS.values())), len(_BASE_CELLS))
        per = fit if per is None else min(per, fit)
    return shard_ranges(r["episodes"], per)


_SHARDS = {t: rollout_shards(t) for t in task_ids()}
_SHARDED = [t for t in task_ids() if len(_SHARDS[t]) > 1]
_WHOLE = [t for t in task_ids() if len(_SHARDS[t]) == 1]


def _shard_files(cells, kind):
    """Output paths of ``cells``' shard ``{shard}`` (``ep<a>-<b>``: episodes a .. b-1) under
    the task's ``shards/`` folder (region, variant, task and shard stay wildcards)."""
    return [f.replace("/{task}/", "/{task}/shards/{shard}/", 1)
            for f in _cell_files(cells, kind)]


def _shard_params(cells):
    """Per-cell entries of a task's shard job: the cells' runs restricted to the shard's
    episodes (``run.shard``: [a, b])."""
    cell_fn = _cell_params(cells)

    def fn(wc):
        a, b = (int(x) for x in wc.shard[2:].split("-"))
        entries = cell_fn(wc)
        for c in entries:
            c["params"]["run"] = {**c["params"]["run"], "shard": [a, b]}
        return entries

    return fn


def _merge_params(cells):
    """Per-cell entries of a task's merge job: each cell's own entry (as the unsharded job's)
    plus ``shards``, its shard files in episode order."""
    cell_fn = _cell_params(cells)

    def fn(wc):
        files = {s: [f.format(**dict(wc.items()), shard=s) for f in _shard_files(cells, "parquet")]
                 for s in (f"ep{a}-{b}" for a, b in _SHARDS[wc.task])}
        return [{**c, "shards": [files[s][i] for s in files]}
                for i, c in enumerate(cell_fn(wc))]

    return fn


if _BASE_CELLS and _WHOLE:

    # Every non-learned cell of one task (methods x tiers, the currents-off and forcing
    # ablations: the same episodes) in one job: one process start and one kernel load for
    # all of them. Outputs stay one Parquet file (and one provenance record) per cell.
    rule rollout_task:
        conda:
            PY_ENV
        input:
            grid=rules.export_grid.output.npz,
            scene=ladder_scene,
            kernel=rules.compile_kernel.output.record,
        output:
            parquet=_cell_files(_BASE_CELLS, "parquet"),
            prov=_cell_files(_BASE_CELLS, "prov"),
        log:
            "logs/rollouts/{region}/{variant}/{task}/rollout_task.log",
        benchmark:
            "results/benchmarks/rollouts/{region}/{variant}/{task}/rollout_task.tsv"
        wildcard_constraints:
            task="|".join(map(re.escape, _WHOLE)),
        params:
            cells=_cell_params(_BASE_CELLS),
        threads: lambda wc: config["rollouts"]["threads"]
        resources:
            mem_mb=2000,
            runtime=60,
        group:
            "rollouts"
        script:
            "../scripts/rollout_cells.py"


if _BASE_CELLS and _SHARDED:

    _merge_cells = _merge_params(_BASE_CELLS)

    localrules:
        merge_rollout_shards,

    # A sharded task (rollouts.shard_episodes / shard_minutes): one job per (task, shard)
    # runs every non-learned cell of the task for the shard's episodes (the same rows, bit
    # for bit, as the whole cell's); the shard files are temporary. Its runtime request is
    # twice rollouts.shard_minutes where that is set.
    rule rollout_task_shard:
        conda:
            PY_ENV
        input:
            grid=rules.export_grid.output.npz,
            scene=ladder_scene,
            kernel=rules.compile_kernel.output.record,
        output:
            parquet=temp(_shard_files(_BASE_CELLS, "parquet")),
            prov=temp(_shard_files(_BASE_CELLS, "prov")),
        log:
            "logs/rollouts/{region}/{variant}/{task}/shards/{shard}/rollout_task.log",
        benchmark:
            "results/benchmarks/rollouts/{region}/{variant}/{task}/shards/{shard}/rollout_task.tsv"
        wildcard_constraints:
            shard=r"ep\d+-\d+",
            task="|".join(map(re.escape, _SHARDED)),
        params:
            cells=_shard_params(_BASE_CELLS),
        threads: lambda wc: config["rollouts"]["threads"]
        resources:
            mem_mb=2000,
            runtime=(60 if config["rollouts"].get("shard_minutes") is None
                     else max(5, math.ceil(2 * config["rollouts"]["shard_minutes"]))),
        group:
            "rollouts"
        script:
            "../scripts/rollout_cells.py"

    # The task's cell files from their shards: byte for byte what rollout_task writes.
    # Not in group "rollouts": it would join every shard of the task into one cluster job.
    rule merge_rollout_shards:
        conda:
            PY_ENV
        input:
            shards=lambda wc: [f for c in _merge_cells(wc) for f in c["shards"]],
        output:
            parquet=_cell_files(_BASE_CELLS, "parquet"),
            prov=_cell_files(_BASE_CELLS, "prov"),
        log:
            "logs/rollouts/{region}/{variant}/{task}/merge_rollout_shards.log",
        wildcard_constraints:
            task="|".join(map(re.escape, _SHARDED)),
        params:
            cells=_merge_cells,
        threads: 1
        resources:
            mem_mb=1000,
            runtime=10,
        script:
            "../scripts/merge_rollout_shards.py"


if _BC_CELLS:

    # Method bc's cells of one task: they wait for its trained weights.
    rule rollout_task_bc:
        conda:
            PY_ENV
        priority: 20
        input:
            grid=rules.export_grid.output.npz,
            scene=ladder_scene,
            kernel=rules.compile_kernel.output.record,
            weights="results/bc/{region}/{variant}/weights.npz",
        output:
            parquet=_cell_files(_BC_CELLS, "parquet"),
            prov=_cell_files(_BC_CELLS, "prov"),
        log:
            "logs/rollouts/{region}/{variant}/{task}/rollout_task_bc.log",
        benchmark:
            "results/benchmarks/rollouts/{region}/{variant}/{task}/rollout_task_bc.tsv"
        params:
            cells=_cell_params(_BC_CELLS),
        threads: lambda wc: config["rollouts"]["threads"]
        resources:
            mem_mb=2000,
            runtime=60,
        group:
            "rollouts"
        script:
            "../scripts/rollout_cells.py"


# What drives a ladder cell (oneocean.reporting.ablations): every ablation cell of one task in one job,
# the heuristic given the true current or its true position (ablations.info) and the stressor
# cells (Tier 1 with one tier key at its Tier-3 value, Tier 3 with it at its Tier-1 value).
# One rule per task, rollout_ablation_<task>, because each task's tier keys are its own.
for _task in config["rollouts"]["tasks"]:
    _cells = ablation_cells(_task)
    if not _cells:
        continue

    rule:
        name:
            ablation_rule_name(_task)
        conda:
            PY_ENV
        input:
            grid=rules.export_grid.output.npz,
            scene=ladder_scene,
            kernel=f"results/kernels/{{region}}/{{variant}}/{_task}.json",
        output:
            parquet=_ablation_files(_task, _cells, "parquet"),
            prov=_ablation_files(_task, _cells, "prov"),
        log:
            f"logs/rollouts/{{region}}/{{variant}}/{_task}/rollout_ablation.log",
        benchmark:
            f"results/benchmarks/rollouts/{{region}}/{{variant}}/{_task}/rollout_ablation.tsv"
        params:
            cells=_ablation_params(_task, _cells),
        threads: lambda wc: config["rollouts"]["threads"]
        resources:
            mem_mb=2000,
            runtime=60,
        group:
            "rollouts"
        script:
            "../scripts/rollout_cells.py"


# Fig. 7: one task at one tier for several team sizes n, in one job.
rule rollout_team:
    conda:
        PY_ENV
    input:
        grid=rules.export_grid.output.npz,
        scene=ladder_scene,
        kernel=rules.compile_kernel.output.record,
    output:
        parquet=[f"results/rollouts/{{region}}/{{variant}}/{{task}}/tier{{tier}}/{{method}}_n{n}.parquet"
                 for n in team_sizes()],
        prov=[f"results/provenance/rollouts/{{region}}/{{variant}}/{{task}}/tier{{tier}}/{{method}}_n{n}.json"
              for n in team_sizes()],
    log:
        "logs/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_team.log",
    benchmark:
        "results/benchmarks/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_team.tsv"
    params:
        cells=_team_params,
    threads: lambda wc: config["rollouts"]["threads"]
    resources:
        mem_mb=2000,
        runtime=60,
    group:
        "rollouts"
    script:
        "../scripts/rollout_cells.py"


rule table_ladder:
    conda:
        PY_ENV
    input:
        cells=rollout_targets() + currents_off_targets(),
        replicate=replicate_targets(),
    output:
        md=report("results/tables/{region}/ladder.md", caption="../report/ladder.rst",
                  category="Tables"),
        prov="results/provenance/tables/{region}/ladder.json",
    log:
        "logs/tables/{region}/ladder.log",
    params:
        seed=lambda wc: config["rollouts"]["seed"],
        code=code_version("oneocean.reporting.ladder", "oneocean.reporting.cells",
                          "oneocean.reporting.stats", "oneocean.registry"),
    threads: 1
    script:
        "../scripts/table_ladder.py"

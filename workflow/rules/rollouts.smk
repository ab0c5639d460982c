# Stage 4: core-backend rollouts, one job per (variant, task, tier, method) cell; episodes are
# batched inside one numba kernel.


# the code a cell of one task depends on (oneocean.codeversion): editing one task's module,
# heuristic or tier table reruns only its cells; hashed once per task and parse
def rollout_code(wc):
    return task_code(wc.task)


def _rollout_params(currents, forcing=None):
    """The run settings of a cell: the config's, or an ablation's forcing ("gain": the
    forcing ablation's gain on the data currents; "tide": the data plus its tide term)."""

    def fn(wc):
        r = config["rollouts"]
        run = {**{k: r[k] for k in ("episodes", "seed", "dynamics", "current_gain", "tide")},
               "currents": currents, "n_agents": int(wc.n) if hasattr(wc, "n") else None}
        fa = r["forcing_ablation"]
        if forcing == "gain":
            run["current_gain"] = fa["gain"] * r["current_gain"]
        elif forcing == "tide":
            run["tide"] = dict(fa["tide"])
        return run

    return fn


def bc_weights(wc):
    """Method bc's trained weights (the bc_train rule's output); no input for other methods."""
    return f"results/bc/{wc.region}/{wc.variant}/weights.npz" if wc.method == "bc" else []


rule rollout_cell:
    input:
        grid=rules.export_grid.output.npz,
        weights=bc_weights,
    output:
        parquet="results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}.parquet",
        prov="results/provenance/rollouts/{region}/{variant}/{task}/tier{tier}/{method}.json",
    log:
        "logs/rollouts/{region}/{variant}/{task}/tier{tier}/{method}.log",
    benchmark:
        "results/benchmarks/rollouts/{region}/{variant}/{task}/tier{tier}/{method}.tsv"
    params:
        run=_rollout_params(True),
        code=rollout_code,
    threads: lambda wc: config["rollouts"]["threads"]
    script:
        "../scripts/rollout_cell.py"


# The currents-off ablation (g = 0, no tides): the same episodes as the cell above.
use rule rollout_cell as rollout_cell_currents_off with:
    output:
        parquet="results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_currents-off.parquet",
        prov="results/provenance/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_currents-off.json",
    log:
        "logs/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_currents-off.log",
    benchmark:
        "results/benchmarks/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_currents-off.tsv"
    params:
        run=_rollout_params(False),
        code=rollout_code,


# The currents ablation's other forcings (doubled gain, + synthetic tide): the same episodes.
use rule rollout_cell as rollout_cell_gain with:
    output:
        parquet="results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_gain.parquet",
        prov="results/provenance/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_gain.json",
    log:
        "logs/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_gain.log",
    benchmark:
        "results/benchmarks/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_gain.tsv"
    params:
        run=_rollout_params(True, "gain"),
        code=rollout_code,


use rule rollout_cell as rollout_cell_tide with:
    output:
        parquet="results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_tide.parquet",
        prov="results/provenance/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_tide.json",
    log:
        "logs/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_tide.log",
    benchmark:
        "results/benchmarks/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_tide.tsv"
    params:
        run=_rollout_params(True, "tide"),
        code=rollout_code,


# Fig. 7: one task at one tier for several team sizes n.
use rule rollout_cell as rollout_cell_team with:
    output:
        parquet="results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_n{n}.parquet",
        prov="results/provenance/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_n{n}.json",
    log:
        "logs/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_n{n}.log",
    benchmark:
        "results/benchmarks/rollouts/{region}/{variant}/{task}/tier{tier}/{method}_n{n}.tsv"
    wildcard_constraints:
        n=r"\d+",
    params:
        run=_rollout_params(True),
        code=rollout_code,


rule table_ladder:
    input:
        cells=rollout_targets() + currents_off_targets(),
    output:
        md="results/tables/{region}/ladder.md",
        prov="results/provenance/tables/{region}/ladder.json",
    log:
        "logs/tables/{region}/ladder.log",
    params:
        seed=lambda wc: config["rollouts"]["seed"],
        code=code_version("oneocean.ladder", "oneocean.registry"),
    threads: 1
    script:
        "../scripts/table_ladder.py"

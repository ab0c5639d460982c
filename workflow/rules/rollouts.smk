# Stage 4: core-backend rollouts, one job per (variant, task, tier, method) cell; episodes are
# batched inside one numba kernel.


# hashed once per workflow parse (shared by the data and the currents-off rules)
ROLLOUT_CODE = code_version(
    "oneocean.tasks", "oneocean.methods", "oneocean.engine", "oneocean.models", "oneocean.data"
)


def _rollout_params(currents):
    def fn(wc):
        r = config["rollouts"]
        return {**{k: r[k] for k in ("episodes", "seed", "dynamics", "current_gain", "tide")},
                "currents": currents}

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
        code=ROLLOUT_CODE,
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
        code=ROLLOUT_CODE,


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


rule table_task_success:
    input:
        cells=rollout_targets(),
    output:
        tex="results/tables/task_success_by_tier.tex",
        prov="results/provenance/tables/task_success_by_tier.json",
    log:
        "logs/tables/task_success_by_tier.log",
    params:
        code=code_version("oneocean.tables", "oneocean.ladder", "oneocean.registry", "oneocean.data"),
    threads: 1
    script:
        "../scripts/table_task_success.py"

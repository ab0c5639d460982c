# Stage 4: core-backend rollouts, one job per (variant, task, tier, method) cell; episodes are
# batched inside one numba kernel.


rule rollout_cell:
    input:
        grid=rules.export_grid.output.npz,
    output:
        parquet="results/rollouts/{region}/{variant}/{task}/tier{tier}/{method}.parquet",
        prov="results/provenance/rollouts/{region}/{variant}/{task}/tier{tier}/{method}.json",
    log:
        "logs/rollouts/{region}/{variant}/{task}/tier{tier}/{method}.log",
    benchmark:
        "results/benchmarks/rollouts/{region}/{variant}/{task}/tier{tier}/{method}.tsv"
    params:
        run=lambda wc: {k: config["rollouts"][k] for k in ("episodes", "seed", "dynamics")},
        code=code_version("oneocean.tasks", "oneocean.methods", "oneocean.engine", "oneocean.models",
                          "oneocean.data"),
    threads: lambda wc: config["rollouts"]["threads"]
    script:
        "../scripts/rollout_cell.py"


rule table_task_success:
    input:
        cells=rollout_targets(),
    output:
        tex="results/tables/task_success_by_tier.tex",
        prov="results/provenance/tables/task_success_by_tier.json",
    log:
        "logs/tables/task_success_by_tier.log",
    params:
        code=code_version("oneocean.tables", "oneocean.registry", "oneocean.data"),
    threads: 1
    script:
        "../scripts/table_task_success.py"

# Behaviour cloning: teacher dataset (training seeds) -> weights (+ report, loss figure).
# The bc rollout cells (rollouts.smk) take the weights as an input, so the chain
# dataset -> weights -> rollouts is in the DAG and the manifest, and retraining happens only
# when the dataset, the settings or the BC code change.

rule bc_dataset:
    conda:
        PY_ENV

    priority: 20
    input:
        grid=rules.export_grid.output.npz,
        kernels=lambda wc: expand("results/kernels/{region}/{variant}/{task}.json",
                                  region=wc.region, variant=wc.variant, task=bc_cells()[0]),
    output:
        parquet="results/bc/{region}/{variant}/dataset.parquet",
        prov="results/provenance/bc/{region}/{variant}/dataset.json",
    log:
        "logs/bc/{region}/{variant}/dataset.log",
    benchmark:
        "results/benchmarks/bc/{region}/{variant}/dataset.tsv"
    params:
        tasks=lambda wc: bc_cells()[0],
        tiers=lambda wc: bc_cells()[1],
        dynamics=lambda wc: config["rollouts"]["dynamics"],
        evaluation_seed=lambda wc: config["rollouts"]["seed"],
        bc=lambda wc: {k: config["bc"][k] for k in ("train_seeds", "episodes", "stride", "max_rows",
                                                     "noise")},
        code=lambda wc: tasks_code(bc_cells()[0]),
    threads: lambda wc: config["rollouts"]["threads"]
    # measured 41 s, 355 MB
    resources:
        mem_mb=1000,
        runtime=30,
    script:
        "../scripts/bc_dataset.py"


rule bc_train:
    conda:
        PY_ENV


    priority: 20
    input:
        dataset=rules.bc_dataset.output.parquet,
    output:
        weights="results/bc/{region}/{variant}/weights.npz",
        report="results/bc/{region}/{variant}/training_report.json",
        png=report("results/figures/{region}/{variant}/bc_training.png",
                   caption="../report/bc_training.rst", category="Figures"),
        pdf="results/figures/{region}/{variant}/bc_training.pdf",
        prov="results/provenance/bc/{region}/{variant}/weights.json",
    log:
        "logs/bc/{region}/{variant}/train.log",
    benchmark:
        "results/benchmarks/bc/{region}/{variant}/train.tsv"
    params:
        bc=lambda wc: {k: config["bc"][k] for k in ("hidden", "epochs", "batch_size",
                                                     "learning_rate", "alpha", "val_fraction",
                                                     "seed")},
        code=code_version("oneocean.methods.bc", "oneocean.tasks.learned"),
    threads: 1
    # measured 137 s, 510 MB
    resources:
        mem_mb=2000,
        runtime=30,
    script:
        "../scripts/bc_train.py"

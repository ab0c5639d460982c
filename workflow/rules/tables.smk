# Tables: LaTeX (booktabs) tables collected by the paper_tables target.


rule table_dataset_variants:
    input:
        metadata=expand(
            "results/product/{region}/{variant}/metadata.json",
            region=REGION,
            variant=VARIANTS,
        ),
    output:
        tex="results/tables/dataset_variants.tex",
        prov="results/provenance/tables/dataset_variants.json",
    log:
        "logs/tables/dataset_variants.log",
    params:
        region=REGION,
        code=code_version("oneocean.tables"),
    threads: 1
    script:
        "../scripts/table_dataset_variants.py"


rule paper_tables:
    input:
        "results/tables/dataset_variants.tex",
        "results/tables/task_success_by_tier.tex",
        f"results/tables/{REGION}/ladder.md",
        f"results/tables/{REGION}/planning_performance.tex",
        f"results/tables/{REGION}/planning_cost.tex",
        figure_targets(),
        export_targets(),
        "results/manifest.json",

# Tables: LaTeX (booktabs) tables collected by the paper_tables target.


# Tables read finished cells and write a few kB: run on the submit host, not submitted.
localrules:
    table_dataset_variants,
    table_systems,
    table_task_ladder,
    table_headline,
    table_task_success,
    table_difficulty,
    table_currents_ablation,
    table_information_ablation,
    table_tier_stressors,
    paper_tables,


rule table_dataset_variants:
    conda:
        PY_ENV
    input:
        metadata=expand(
            "results/product/{{region}}/{variant}/metadata.json",
            variant=VARIANTS,
        ),
    output:
        tex=report("results/tables/{region}/dataset_variants.tex",
                   caption="../report/table.rst", category="Tables"),
        prov="results/provenance/tables/{region}/dataset_variants.json",
    log:
        "logs/tables/{region}/dataset_variants.log",
    params:
        region=REGION,
        code=code_version("oneocean.reporting.tables", "oneocean.reporting.latex"),
    threads: 1
    script:
        "../scripts/table_dataset_variants.py"


TABLES_CODE = code_version("oneocean.reporting.tables", "oneocean.reporting.cells",
                           "oneocean.reporting.stats", "oneocean.reporting.latex",
                           "oneocean.reporting.planning", "oneocean.registry", "oneocean.data",
                           "oneocean.reporting.ablations")

# Table I: the systems compared (oneocean/data/systems.yaml; no cells needed).
rule table_systems:
    conda:
        PY_ENV
    output:
        **_table_rule_io("systems"),
    log:
        "logs/tables/{region}/systems.log",
    params:
        code=code_version("oneocean.reporting.overview", "oneocean.reporting.latex",
                          "oneocean.data"),
    threads: 1
    script:
        "../scripts/table_paper.py"


# Table II: the task ladder (registry and tier tables).
rule table_task_ladder:
    conda:
        PY_ENV
    output:
        **_table_rule_io("task_ladder"),
    log:
        "logs/tables/{region}/task_ladder.log",
    params:
        code=TABLES_CODE,
    threads: 1
    script:
        "../scripts/table_paper.py"


# Table III: per method, Tier-2/3 macro SR, E, Coll and Tier-3 key metrics.
rule table_headline:
    conda:
        PY_ENV
    input:
        cells=rollout_targets(),
    output:
        **_table_rule_io("headline"),
    log:
        "logs/tables/{region}/headline.log",
    params:
        code=TABLES_CODE,
    threads: 1
    script:
        "../scripts/table_paper.py"


# Table V: per task, every method at every tier.
rule table_task_success:
    conda:
        PY_ENV
    input:
        cells=rollout_targets(),
    output:
        **_table_rule_io("task_success_by_tier"),
    log:
        "logs/tables/{region}/task_success_by_tier.log",
    params:
        code=TABLES_CODE,
    threads: 1
    script:
        "../scripts/table_paper.py"


# The difficulty ladder of the heuristic: T1/T2/T3 and the drops.
rule table_difficulty:
    conda:
        PY_ENV
    input:
        cells=rollout_targets(),
    output:
        **_table_rule_io("difficulty_heuristic"),
    log:
        "logs/tables/{region}/difficulty_heuristic.log",
    params:
        code=TABLES_CODE,
    threads: 1
    script:
        "../scripts/table_paper.py"


# The currents ablation of the heuristic: off / data-grounded / doubled / + synthetic tide.
rule table_currents_ablation:
    conda:
        PY_ENV
    input:
        cells=rollout_targets() + currents_off_targets() + forcing_targets(),
    output:
        **_table_rule_io("currents_ablation"),
    log:
        "logs/tables/{region}/currents_ablation.log",
    params:
        tier=lambda wc: max(config["rollouts"]["forcing_ablation"]["tiers"]),
        code=TABLES_CODE,
    threads: 1
    script:
        "../scripts/table_paper.py"


# What drives a ladder cell (1): the heuristic at one tier with its sensors, the true current,
# its true position, the currents off, and the oracle.
rule table_information_ablation:
    conda:
        PY_ENV
    input:
        cells=information_table_cells(),
    output:
        **_table_rule_io("information_ablation", caption="information_ablation"),
    log:
        "logs/tables/{region}/information_ablation.log",
    params:
        tier=lambda wc: config["ablations"]["info"]["tier"],
        code=TABLES_CODE,
    threads: 1
    script:
        "../scripts/table_paper.py"


# What drives a ladder cell (2): one tier key at a time between Tier 1 and Tier 3, its share of
# the T1 -> T3 drop, and the check that no key alone makes more than three quarters of it.
rule table_tier_stressors:
    conda:
        PY_ENV
    input:
        cells=stressor_table_cells(),
    output:
        **_table_rule_io("tier_stressors", caption="tier_stressors"),
    log:
        "logs/tables/{region}/tier_stressors.log",
    params:
        code=TABLES_CODE,
    threads: 1
    script:
        "../scripts/table_paper.py"


rule paper_tables:
    conda:
        PY_ENV
    input:
        PAPER_TABLES,
        f"results/tables/{REGION}/ladder.md",
        f"results/tables/{REGION}/planning_performance.tex",
        f"results/tables/{REGION}/planning_cost.tex",
        figure_targets(),
        PAPER_FIGURES,
        export_targets(),
        scene_targets(),
        f"results/manifest/{REGION}.json",

# Figures (PNG + PDF, byte-stable): Fig. 3 the current field over bathymetry for every
# variant; Fig. 4 the pollution model's species; Fig. 6 the heuristic's difficulty ladder;
# Fig. 5 one-episode snapshots; Fig. 7 the SPC team-size sweep.

FIGURES_CODE = code_version("oneocean.reporting.figures", "oneocean.reporting.cells",
                            "oneocean.reporting.stats")


# Figures drawn from finished cells: on the submit host, not submitted.
localrules:
    figure_ladder,
    figure_team_sweep,
    figure_overview_registry,
    figure_overview_workflow,


rule figure_current_field:
    conda:
        PY_ENV
    input:
        product=rules.merge_variant.output.nc,
    output:
        png=report("results/figures/{region}/{variant}/current_field.png",
                   caption="../report/fig3_current_field.rst", category="Figures",
                   subcategory="Fig. 3 current field"),
        pdf="results/figures/{region}/{variant}/current_field.pdf",
        prov="results/provenance/figures/{region}/{variant}/current_field.json",
    log:
        "logs/figures/{region}/{variant}/current_field.log",
    params:
        view=lambda wc: config["figure"],
        code=FIGURES_CODE,
    threads: 1
    # no benchmark recorded: sized like the exports of the same variant
    resources:
        mem_mb=1000,
        runtime=10,
    group:
        "variant"
    script:
        "../scripts/figure_current_field.py"

# Fig. 4: multi-species pollution fields from the reaction model (no region data).
rule figure_pollution_species:
    conda:
        PY_ENV
    output:
        **_figure_io("pollution_species", "fig4_pollution_species"),
    log:
        "logs/figures/{region}/pollution_species.log",
    params:
        seed=lambda wc: config["rollouts"]["seed"],
        code=FIGURES_CODE + code_version("oneocean.models"),
    threads: 1
    # no benchmark recorded: sized conservatively (one small reaction-model run)
    resources:
        mem_mb=1000,
        runtime=15,
    script:
        "../scripts/figure_paper.py"


# Fig. 6: success per tier and the drops, heuristic cells.
rule figure_ladder:
    conda:
        PY_ENV
    input:
        cells=[p for p in rollout_targets() if Path(p).name == "heuristic.parquet"],
    output:
        **_figure_io("ladder", "fig6_ladder"),
    log:
        "logs/figures/{region}/ladder.log",
    params:
        code=FIGURES_CODE,
    threads: 1
    script:
        "../scripts/figure_paper.py"


# Fig. 5: one episode per task, snapshots over the bathymetry (plume, object, scan, school).
rule figure_snapshots:
    conda:
        PY_ENV
    input:
        grid=lambda wc: EXPORT_GRID_PATH.format(region=wc.region,
                                                variant=config["rollouts"]["variant"]),
        kernels=lambda wc: [f"results/kernels/{wc.region}/{config['rollouts']['variant']}/{t}.json"
                            for t in config["snapshots"]["tasks"]],
    output:
        **_figure_io("snapshots", "fig5_snapshots"),
    log:
        "logs/figures/{region}/snapshots.log",
    params:
        tasks=lambda wc: config["snapshots"]["tasks"],
        tier=lambda wc: config["snapshots"]["tier"],
        method=lambda wc: config["snapshots"]["method"],
        episode=lambda wc: config["snapshots"]["episode"],
        seed=lambda wc: config["rollouts"]["seed"],
        episodes=lambda wc: config["rollouts"]["episodes"],
        dynamics=lambda wc: config["rollouts"]["dynamics"],
        code=FIGURES_CODE + code_version("oneocean.reporting.snapshots") + tasks_code(config["snapshots"]["tasks"]),
    threads: 1
    # no benchmark recorded: sized conservatively (one episode per task, cached kernels)
    resources:
        mem_mb=2000,
        runtime=30,
    script:
        "../scripts/figure_snapshots.py"


# Fig. 7: SPC at Tier 2 for team sizes 2..10.
rule figure_team_sweep:
    conda:
        PY_ENV
    input:
        cells=team_targets(),
    output:
        **_figure_io("team_sweep", "fig7_team_sweep"),
    log:
        "logs/figures/{region}/team_sweep.log",
    params:
        code=FIGURES_CODE,
    threads: 1
    script:
        "../scripts/figure_paper.py"


# Fig. 1: what is implemented, from the registry (tasks x backends/tiers, sources, methods).
rule figure_overview_registry:
    conda:
        PY_ENV
    output:
        **_figure_io("overview_registry", "fig1_overview_registry"),
    log:
        "logs/figures/{region}/overview_registry.log",
    params:
        code=FIGURES_CODE + code_version("oneocean.reporting.overview", "oneocean.registry",
                                         "oneocean.data", "oneocean.sources",
                                         "oneocean.backends.protocol", "oneocean.vocab"),
    threads: 1
    script:
        "../scripts/figure_paper.py"


# Fig. 2: the workflow's rule graph (snakemake --rulegraph of paper_tables, this run's config).
rule figure_overview_workflow:
    conda:
        PY_ENV
    output:
        **_figure_io("overview_workflow", "fig2_overview_workflow"),
    log:
        "logs/figures/{region}/overview_workflow.log",
    params:
        target="paper_tables",
        workflow=workflow_source_version(),
        code=FIGURES_CODE + code_version("oneocean.reporting.overview"),
    threads: 1
    script:
        "../scripts/figure_paper.py"

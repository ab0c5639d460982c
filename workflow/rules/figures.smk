# Figures (PNG + PDF, byte-stable): Fig. 3 the current field over bathymetry for every
# variant; Fig. 4 the pollution model's species; Fig. 6 the heuristic's difficulty ladder;
# Fig. 7 the SPC team-size sweep.

FIGURES_CODE = code_version("oneocean.figures", "oneocean.ladder")


rule figure_current_field:
    input:
        product=rules.merge_variant.output.nc,
    output:
        png="results/figures/{region}/{variant}/current_field.png",
        pdf="results/figures/{region}/{variant}/current_field.pdf",
        prov="results/provenance/figures/{region}/{variant}/current_field.json",
    log:
        "logs/figures/{region}/{variant}/current_field.log",
    params:
        view=lambda wc: config["figure"],
        code=FIGURES_CODE,
    threads: 1
    script:
        "../scripts/figure_current_field.py"


def _figure_io(name):
    return {
        "png": f"results/figures/{{region}}/{name}.png",
        "pdf": f"results/figures/{{region}}/{name}.pdf",
        "prov": f"results/provenance/figures/{{region}}/{name}.json",
    }


# Fig. 4: multi-species pollution fields from the reaction model (no region data).
rule figure_pollution_species:
    output:
        **_figure_io("pollution_species"),
    log:
        "logs/figures/{region}/pollution_species.log",
    params:
        seed=lambda wc: config["rollouts"]["seed"],
        code=FIGURES_CODE + code_version("oneocean.models"),
    threads: 1
    script:
        "../scripts/figure_paper.py"


# Fig. 6: success per tier and the drops, heuristic cells.
rule figure_ladder:
    input:
        cells=[p for p in rollout_targets() if p.endswith("/heuristic.parquet")],
    output:
        **_figure_io("ladder"),
    log:
        "logs/figures/{region}/ladder.log",
    params:
        code=FIGURES_CODE,
    threads: 1
    script:
        "../scripts/figure_paper.py"


# Fig. 7: SPC at Tier 2 for team sizes 2..10.
rule figure_team_sweep:
    input:
        cells=team_targets(),
    output:
        **_figure_io("team_sweep"),
    log:
        "logs/figures/{region}/team_sweep.log",
    params:
        code=FIGURES_CODE,
    threads: 1
    script:
        "../scripts/figure_paper.py"

from pathlib import Path

from oneocean.pipeline import smk
from oneocean.reporting import figures, overview


def make(s):
    if s.rule == "figure_pollution_species":
        figures.plot_pollution_species(s.output.png, seed=int(s.params.seed))
    elif s.rule == "figure_ladder":
        figures.plot_ladder(list(s.input.cells), s.output.png, method="heuristic")
    elif s.rule == "figure_team_sweep":
        figures.plot_team_sweep(list(s.input.cells), s.output.png)
    elif s.rule == "figure_overview_registry":
        overview.plot_registry_overview(s.output.png)
    elif s.rule == "figure_overview_workflow":
        # the top-level Snakefile of this workflow (scriptdir: workflow/scripts)
        dot = overview.rule_graph(s.params.target, config=dict(s.config),
                                  snakefile=Path(s.scriptdir).resolve().parents[1] / "Snakefile")
        overview.plot_workflow(dot, s.output.png)
    elif s.rule == "figure_rl_curves":
        figures.plot_rl_curves(list(s.input.reports), s.output.png)
    else:
        raise ValueError(f"figure_paper.py: unknown rule {s.rule}")


smk.run(snakemake, make)

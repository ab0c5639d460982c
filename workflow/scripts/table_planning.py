from oneocean.pipeline import smk
from oneocean.reporting.planning import planning_tables

smk.run(
    snakemake,
    lambda s: planning_tables(
        list(s.input.cells), s.output.perf, s.output.cost,
        tier=s.params.planning["tier"], gain=s.params.planning["current_gain"],
        episodes=s.params.planning["episodes"],
        cost_episodes=s.params.planning["cost_episodes"], configured_llms=s.params.llms,
    ),
)

from oneocean.pipeline import smk
from oneocean.methods.llm.rollout import planner_cell_to_file

smk.run(
    snakemake,
    lambda s: planner_cell_to_file(
        s.input.grid, s.output.parquet, s.wildcards.task, int(s.params.run["tier"]),
        dict(s.params.model), s.params.run["episodes"], s.params.run["seed"],
        s.params.run["dynamics"], s.params.run["current_gain"], s.params.every,
        s.params.cache_dir, threads=s.threads,
    ),
)

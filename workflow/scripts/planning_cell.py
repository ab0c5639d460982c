from oneocean.pipeline import smk
from oneocean.tasks import rollout_to_file

smk.run(
    snakemake,
    lambda s: rollout_to_file(
        s.input.grid, s.output.parquet, s.wildcards.task, int(s.params.run["tier"]),
        s.wildcards.method, s.params.run["episodes"], s.params.run["seed"],
        s.params.run["dynamics"], threads=s.threads,
        current_gain=s.params.run["current_gain"], weights=smk.optional_input(s, "weights"),
    ),
)

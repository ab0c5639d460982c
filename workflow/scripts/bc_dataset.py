from oneocean.pipeline import smk
from oneocean.methods.bc.dataset import dataset_to_file

smk.run(
    snakemake,
    lambda s: dataset_to_file(
        s.input.grid, s.output.parquet, s.params.tasks, s.params.tiers,
        s.params.bc["train_seeds"], episodes=s.params.bc["episodes"],
        dynamics=s.params.dynamics, stride=s.params.bc["stride"],
        max_rows=s.params.bc["max_rows"], evaluation_seed=s.params.evaluation_seed,
        noise=s.params.bc["noise"], threads=s.threads,
    ),
)

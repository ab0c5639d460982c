from oneocean.pipeline import smk
from oneocean.methods.bc.train import train_to_files

smk.run(
    snakemake,
    lambda s: train_to_files(
        s.input.dataset, s.output.weights, s.output.report, s.output.png, **s.params.bc
    ),
)

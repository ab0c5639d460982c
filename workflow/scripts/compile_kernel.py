from oneocean.pipeline import smk
from oneocean.tasks import compile_kernel

smk.run(
    snakemake,
    lambda s: compile_kernel(s.input.grid, s.output.record, s.wildcards.task, s.params.tiers,
                             s.params.dynamics),
)

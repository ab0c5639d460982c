from oneocean.pipeline import smk
from oneocean.reporting import tables
from oneocean.methods.ppo import policy  # noqa: F401  (registers the method ppo)

smk.run(snakemake, lambda s: tables.task_success_table(list(s.input.cells), s.output.tex,
                                                      region=s.wildcards.region))

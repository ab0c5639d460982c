from oneocean.pipeline import smk
from oneocean.reporting.ladder import write_ladder

smk.run(snakemake, lambda s: write_ladder(s.input.cells, s.output.md, s.wildcards.region,
                                          s.params.seed, replicate=s.input.replicate))

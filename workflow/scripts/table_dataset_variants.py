from oneocean.pipeline import smk
from oneocean.reporting.tables import dataset_variants_table

smk.run(snakemake, lambda s: dataset_variants_table(list(s.input.metadata), s.output.tex))

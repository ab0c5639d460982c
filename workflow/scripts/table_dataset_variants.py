from oneocean import smk
from oneocean.tables import dataset_variants_table

smk.run(snakemake, lambda s: dataset_variants_table(list(s.input.metadata), s.output.tex))

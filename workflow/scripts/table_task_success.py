from oneocean import smk
from oneocean.tables import task_success_table

smk.run(snakemake, lambda s: task_success_table(list(s.input.cells), s.output.tex))

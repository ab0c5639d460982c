from oneocean.pipeline import smk
from oneocean.reporting.scene_tables import write_scene_tables

smk.run(snakemake, lambda s: write_scene_tables(
    s.input.cells, s.output.tex, s.output.compare, s.output.md, s.wildcards.region,
    s.params.compare))

from oneocean.pipeline import smk
from oneocean.tasks import merge_shards


def merge_cell(s, cell, path):
    merge_shards(cell["shards"], path)


smk.run_cells(snakemake, merge_cell)

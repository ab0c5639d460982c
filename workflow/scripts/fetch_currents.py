from oneocean.pipeline import smk
from oneocean.sources import fetch_currents

smk.run(snakemake, lambda s: fetch_currents(s.params.cfg, s.output.nc, s.params.cache_dir))

from oneocean.pipeline import smk
from oneocean.sources import fetch_bathymetry

smk.run(snakemake, lambda s: fetch_bathymetry(s.params.cfg, s.output.nc, s.params.cache_dir))

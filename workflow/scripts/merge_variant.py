from oneocean.pipeline import smk
from oneocean.product.build import build_product

smk.run(
    snakemake,
    lambda s: build_product(
        s.input.currents, s.input.bathymetry, s.params.cfg, s.wildcards.variant,
        s.output.nc, s.output.metadata,
    ),
)

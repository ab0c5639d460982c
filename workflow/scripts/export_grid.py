from oneocean.pipeline import smk
from oneocean.product.exports import export_grid

smk.run(
    snakemake,
    lambda s: export_grid(s.input.product, s.output.npz,
                          {"region": s.wildcards.region, "variant": s.wildcards.variant}),
)

from oneocean.pipeline import smk
from oneocean.product.exports import export_temporal

smk.run(
    snakemake,
    lambda s: export_temporal(
        s.input.product, s.output.npz, s.params.point["lat"], s.params.point["lon"],
        s.params.point["depth_m"], {"region": s.wildcards.region, "variant": s.wildcards.variant},
    ),
)

from oneocean.pipeline import smk
from oneocean.reporting.figures import plot_current_field

smk.run(
    snakemake,
    lambda s: plot_current_field(
        s.input.product, s.output.png, pitch_deg=s.params.view["pitch_deg"],
        azimuth_deg=s.params.view["azimuth_deg"], depth_m=s.params.view["depth_m"],
    ),
)

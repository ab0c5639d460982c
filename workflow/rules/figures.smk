# Figures: Fig. 3, the current field over bathymetry, for every variant.


rule figure_current_field:
    input:
        product=rules.merge_variant.output.nc,
    output:
        png="results/figures/{region}/{variant}/current_field.png",
        prov="results/provenance/figures/{region}/{variant}/current_field.json",
    log:
        "logs/figures/{region}/{variant}/current_field.log",
    params:
        view=lambda wc: config["figure"],
        code=code_version("oneocean.figures"),
    threads: 1
    script:
        "../scripts/figure_current_field.py"

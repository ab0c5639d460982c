# Stage 2: merge currents, tides and bathymetry onto one regular grid per dataset variant.


rule merge_variant:
    conda:
        PY_ENV


    priority: 10
    input:
        currents=rules.fetch_currents.output.nc,
        bathymetry=rules.fetch_bathymetry.output.nc,
    output:
        nc="results/product/{region}/{variant}/product.nc",
        metadata="results/product/{region}/{variant}/metadata.json",
        prov="results/provenance/product/{region}/{variant}.json",
    log:
        "logs/product/{region}/{variant}.log",
    benchmark:
        "results/benchmarks/product/{region}/{variant}.tsv"
    params:
        cfg=lambda wc: config_section(
            "region", "sources", "synthetic", "cmems", "gebco", "etopo", "files", "variants"
        ),
        code=code_version("oneocean.product", "oneocean.sources", "oneocean.io"),
    threads: 1
    script:
        "../scripts/merge_variant.py"

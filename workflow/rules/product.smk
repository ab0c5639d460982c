# Stage 2: merge currents, tides and bathymetry onto one regular grid per dataset variant.

# product.nc (config product.format: netcdf, the default) or product.zarr (a store: a directory)
PRODUCT_NAME = product_filename(config["product"]["format"])
PRODUCT_PATH = f"results/product/{{region}}/{{variant}}/{PRODUCT_NAME}"


rule merge_variant:
    conda:
        PY_ENV


    priority: 10
    input:
        currents=rules.fetch_currents.output.nc,
        bathymetry=rules.fetch_bathymetry.output.nc,
    output:
        nc=directory(PRODUCT_PATH) if is_zarr(PRODUCT_PATH) else PRODUCT_PATH,
        metadata="results/product/{region}/{variant}/metadata.json",
        prov="results/provenance/product/{region}/{variant}.json",
    log:
        "logs/product/{region}/{variant}.log",
    benchmark:
        "results/benchmarks/product/{region}/{variant}.tsv"
    params:
        cfg=lambda wc: config_section(
            "region", "sources", "synthetic", "cmems", "gebco", "etopo", "files", "variants",
            "product",
        ),
        code=code_version("oneocean.product.build", "oneocean.sources", "oneocean.io",
                          "oneocean.product.ncio", "oneocean.product.zarrio"),
    threads: 1
    # measured <= 25 s, 280 MB; group "variant": a variant's merge, exports and Fig. 3 in
    # one cluster job
    resources:
        mem_mb=1000,
        runtime=15,
    group:
        "variant"
    script:
        "../scripts/merge_variant.py"

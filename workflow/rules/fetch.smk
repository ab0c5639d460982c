# Stage 1: fetch each layer for the region into one canonical NetCDF (atomic, retried,
# never refetched when already present).


# Downloads run on the submit host (compute nodes are often offline); seconds of work.
localrules:
    fetch_currents,
    fetch_bathymetry,


rule fetch_currents:
    conda:
        PY_ENV


    priority: 10
    output:
        nc="results/raw/{region}/currents.nc",
        prov="results/provenance/fetch/{region}/currents.json",
    log:
        "logs/fetch/{region}/currents.log",
    benchmark:
        "results/benchmarks/fetch/{region}/currents.tsv"
    params:
        cfg=lambda wc: config_section("region", "sources", "synthetic", "cmems", "files"),
        cache_dir=lambda wc: f"results/raw/{wc.region}/download",
        code=code_version("oneocean.sources"),
    threads: 2
    script:
        "../scripts/fetch_currents.py"


rule fetch_bathymetry:
    conda:
        PY_ENV


    priority: 10
    output:
        nc="results/raw/{region}/bathymetry.nc",
        prov="results/provenance/fetch/{region}/bathymetry.json",
    log:
        "logs/fetch/{region}/bathymetry.log",
    benchmark:
        "results/benchmarks/fetch/{region}/bathymetry.tsv"
    params:
        cfg=lambda wc: config_section("region", "sources", "synthetic", "gebco", "etopo", "files"),
        cache_dir=lambda wc: f"results/raw/{wc.region}/download",
        code=code_version("oneocean.sources"),
    threads: 1
    script:
        "../scripts/fetch_bathymetry.py"

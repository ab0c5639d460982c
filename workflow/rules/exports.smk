# Stage 3: backend exports of each variant (grid for the core backend, a point time series
# for the scene backend).

# grid.npz / temporal.npz (config exports.format: npz, the default) or grid.zarr /
# temporal.zarr (zarr stores: directories)
EXPORT_GRID_PATH = "results/exports/{region}/{variant}/" + export_filename(
    "grid", config["exports"]["format"])
EXPORT_TEMPORAL_PATH = "results/exports/{region}/{variant}/" + export_filename(
    "temporal", config["exports"]["format"])


rule export_grid:
    conda:
        PY_ENV


    priority: 10
    input:
        product=rules.merge_variant.output.nc,
    output:
        npz=directory(EXPORT_GRID_PATH) if is_zarr(EXPORT_GRID_PATH) else EXPORT_GRID_PATH,
        prov="results/provenance/exports/{region}/{variant}/grid.json",
    log:
        "logs/exports/{region}/{variant}/grid.log",
    benchmark:
        "results/benchmarks/exports/{region}/{variant}/grid.tsv"
    params:
        code=code_version("oneocean.product.exports", "oneocean.product.zarrio"),
    threads: 1
    # measured <= 13 s, 380 MB (group: see merge_variant)
    resources:
        mem_mb=1000,
        runtime=15,
    group:
        "variant"
    script:
        "../scripts/export_grid.py"


rule export_temporal:
    conda:
        PY_ENV
    input:
        product=rules.merge_variant.output.nc,
    output:
        npz=(directory(EXPORT_TEMPORAL_PATH) if is_zarr(EXPORT_TEMPORAL_PATH)
             else EXPORT_TEMPORAL_PATH),
        prov="results/provenance/exports/{region}/{variant}/temporal.json",
    log:
        "logs/exports/{region}/{variant}/temporal.log",
    benchmark:
        "results/benchmarks/exports/{region}/{variant}/temporal.tsv"
    params:
        point=lambda wc: config["temporal_export"],
        code=code_version("oneocean.product.exports", "oneocean.product.zarrio"),
    threads: 1
    # measured <= 13 s, 315 MB (group: see merge_variant)
    resources:
        mem_mb=1000,
        runtime=15,
    group:
        "variant"
    script:
        "../scripts/export_temporal.py"

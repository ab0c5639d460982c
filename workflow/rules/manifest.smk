# The manifest: every artifact's provenance collected in one hash-tracked file.


localrules:
    manifest,


rule manifest:
    conda:
        PY_ENV
    input:
        provenance_targets(),
    output:
        "results/manifest/{region}.json",
    log:
        "logs/manifest/{region}.log",
    script:
        "../scripts/collect_manifest.py"

# The manifest: every artifact's provenance collected in one hash-tracked file.


rule manifest:
    input:
        provenance_targets(),
    output:
        "results/manifest.json",
    log:
        "logs/manifest/manifest.log",
    script:
        "../scripts/collect_manifest.py"

from oneocean.pipeline.manifest import collect_manifest

collect_manifest(list(snakemake.input), snakemake.output[0])

# OneOcean: `snakemake --cores 2` (no target) builds the paper, like `paper_tables`.
include: "workflow/Snakefile"


# Snakemake ignores `default_target` inside an included file, so the default target is set
# here, in the top-level Snakefile.
rule default:
    default_target: True
    input:
        rules.all.input,

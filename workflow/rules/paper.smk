# The paper PDF (optional: needs TeX; not part of the default target): paper/main.tex with
# every generated table and figure of this region, compiled by latexmk
# (`snakemake --cores 2 paper`). Byte-reproducible (fixed date and id, oneocean.reporting.latex).

PAPER_TEX = str(Path(workflow.current_basedir).parents[1] / "paper" / "main.tex")


# latexmk on the submit host (where TeX is installed, beside the tables and figures).
localrules:
    paper,


rule paper:
    conda:
        LATEX_ENV
    input:
        tex=PAPER_TEX,
        parts=paper_inputs(),
    output:
        pdf=f"results/paper/{REGION}/main.pdf",
    log:
        f"logs/paper/{REGION}/latexmk.log",
    params:
        region=REGION,
    threads: 1
    script:
        "../scripts/paper_pdf.py"

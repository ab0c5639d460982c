import sys

from oneocean.errors import OneOceanError
from oneocean.reporting.latex import build_paper

try:
    build_paper(snakemake.input.tex, snakemake.output.pdf, snakemake.params.region,
                "results", log_path=snakemake.log[0])
except OneOceanError as err:
    print(f"paper: {err}", file=sys.stderr)
    sys.exit(1)

from oneocean.reporting import ablations
from oneocean.pipeline import smk
from oneocean.reporting import overview, tables


def make(s):
    out, region = s.output.tex, s.wildcards.region
    cells = list(s.input.cells) if hasattr(s.input, "cells") else []
    if s.rule == "table_systems":
        overview.systems_table(out)
    elif s.rule == "table_task_ladder":
        tables.ladder_spec_table(out)
    elif s.rule == "table_headline":
        tables.headline_table(cells, out, region=region)
    elif s.rule == "table_task_success":
        tables.task_success_table(cells, out, region=region)
    elif s.rule == "table_difficulty":
        tables.difficulty_table(cells, out, method="heuristic", region=region)
    elif s.rule == "table_currents_ablation":
        tables.ablation_table(cells, out, tier=int(s.params.tier), method="heuristic",
                              region=region)
    elif s.rule == "table_information_ablation":
        ablations.information_table(cells, out, tier=int(s.params.tier), method="heuristic",
                                    region=region)
    elif s.rule == "table_tier_stressors":
        ablations.stressor_table(cells, out, method="heuristic", region=region)
    else:
        raise ValueError(f"table_paper.py: unknown rule {s.rule}")


smk.run(snakemake, make)

from oneocean import smk
from oneocean.tasks import rollout_to_file


def run_cell(s, cell, path):
    run = cell["params"]["run"]
    rollout_to_file(
        s.input.grid, path, s.wildcards.task, cell["tier"], cell["method"], run["episodes"],
        run["seed"], run["dynamics"], threads=s.threads, current_gain=run["current_gain"],
        tide=run["tide"], currents=run["currents"], weights=smk.optional_input(s, "weights"),
        n_agents=run.get("n_agents"),
    )


smk.run_cells(snakemake, run_cell)

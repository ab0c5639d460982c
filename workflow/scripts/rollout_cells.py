from oneocean import smk
from oneocean.tasks import rollout_to_file

smk.run_cells(
    snakemake,
    lambda s, cell, path: rollout_to_file(
        s.input.grid, path, s.wildcards.task, int(cell["tier"]), cell["method"],
        cell["run"]["episodes"], cell["run"]["seed"], cell["run"]["dynamics"],
        threads=s.threads, current_gain=cell["run"]["current_gain"], tide=cell["run"]["tide"],
        currents=cell["run"]["currents"], weights=smk.optional_input(s, "weights"),
        n_agents=cell["run"].get("n_agents"),
    ),
)

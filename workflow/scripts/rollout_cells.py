from oneocean import smk
from oneocean.tasks import rollout_to_file


def run_cell(s, cell, path):
    run = cell["params"]["run"]
    # an ablation job's rule is one task's (rollout_ablation_<task>): its cells name the task
    task = cell["wildcards"].get("task") or s.wildcards.task
    rollout_to_file(
        s.input.grid, path, task, cell["tier"], cell["method"], run["episodes"],
        run["seed"], run["dynamics"], threads=s.threads, current_gain=run["current_gain"],
        tide=run["tide"], currents=run["currents"], weights=smk.optional_input(s, "weights"),
        n_agents=run.get("n_agents"), info=run.get("info"),
        tier_overrides=run.get("tier_overrides"),
    )


smk.run_cells(snakemake, run_cell)

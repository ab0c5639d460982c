from oneocean.pipeline import smk
from oneocean.tasks import rollout_to_file


def run_cell(s, cell, path):
    run = cell["params"]["run"]
    # an ablation job's rule is one task's (rollout_ablation_<task>): its cells name the task
    task = cell["wildcards"].get("task") or s.wildcards.task
    backend = run.get("backend", "core")
    scene = None
    if backend != "core":   # rollouts.backend: the cells run in the scene rollouts.scene
        from oneocean.backends.mujoco.store import load_scene

        scene = load_scene(smk.optional_input(s, "scene"))
    rollout_to_file(
        None if scene is not None else s.input.grid, path, task, cell["tier"],
        cell["method"], run["episodes"],
        run["seed"], run["dynamics"], threads=s.threads, current_gain=run["current_gain"],
        tide=run["tide"], currents=run["currents"], weights=smk.optional_input(s, "weights"),
        n_agents=run.get("n_agents"), info=run.get("info"),
        tier_overrides=run.get("tier_overrides"), backend=backend, scene=scene,
        physics_step_s=run.get("physics_step_s"), shard=run.get("shard"),
    )


smk.run_cells(snakemake, run_cell)

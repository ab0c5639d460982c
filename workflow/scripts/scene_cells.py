from oneocean.pipeline import smk
from oneocean.backends.mujoco.store import load_scene
from oneocean.tasks import rollout_to_file


def run_cell(s, cell, path):
    run = cell["params"]["run"]
    scene = load_scene(s.input.scene)
    rollout_to_file(
        None, path, cell["task"], cell["tier"], cell["method"], run["episodes"], run["seed"],
        run["dynamics"], threads=s.threads, weights=smk.optional_input(s, "weights"),
        backend=s.params.backend, scene=scene, physics_step_s=run["physics_step_s"],
    )


smk.run_cells(snakemake, run_cell)

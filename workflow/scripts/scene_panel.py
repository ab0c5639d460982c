from oneocean.pipeline import smk
from oneocean.backends.mujoco.store import load_scene, scene_panel

smk.run(snakemake, lambda s: scene_panel(
    load_scene(s.input.scene), s.wildcards.panel, int(s.params.seed), s.params.dynamics,
    s.output.png, s.params.media, s.params.physics_step_s))

from oneocean.pipeline import smk
from oneocean.backends.mujoco.store import load_scene, scene_media

smk.run(snakemake, lambda s: scene_media(
    load_scene(s.input.scene), s.params.tasks, s.params.tiers, int(s.params.seed),
    s.params.dynamics, list(s.output.frames), s.params.media, s.params.physics_step_s))

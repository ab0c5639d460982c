from oneocean.pipeline import smk
from oneocean.backends.mujoco.store import build_scene_files

smk.run(snakemake, lambda s: build_scene_files(s.params.spec, s.input.grid, s.input.temporal,
                                               s.output.meta))

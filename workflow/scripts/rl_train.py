import logging

from oneocean.pipeline import smk
from oneocean.methods.ppo.train import train_to_files


def train(s):
    rl = s.params.rl
    train_to_files(
        s.input.grid, s.output.policy, s.output.report, s.wildcards.task,
        tiers=rl["tiers_train"], budget_steps=rl["budget_steps"], n_envs=rl["n_envs"],
        seeds=rl["seeds"], dynamics=s.params.dynamics,
        evaluation_seeds=s.params.evaluation_seeds, log=logging.getLogger(f"oneocean.{s.rule}"),
    )


smk.run(snakemake, train)

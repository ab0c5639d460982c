from oneocean.pipeline import smk
from oneocean.methods.ppo.policy import evaluate_to_file


def cell(s):
    run = s.params.run
    evaluate_to_file(
        s.input.policy, s.input.grid, s.output.parquet, s.wildcards.task, int(s.wildcards.tier),
        episodes=run["episodes"], seed=run["seed"], dynamics=run["dynamics"],
        current_gain=run["current_gain"], tide=run["tide"], backend=run["backend"],
        threads=s.threads,
    )


smk.run(snakemake, cell)

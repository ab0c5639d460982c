# Reinforcement learning (method ppo; the optional target rl_baselines, not part of
# paper_tables or all): one PPO training job per task on training seeds (rl_train), its
# evaluation cells on the evaluation seed's episodes in the rollout cells' layout (rl_cell),
# Table V over the RL tasks with the PPO rows (table_task_success_rl) and the manifest of
# this stage (manifest_rl: results/manifest/<region>.rl.json), and the learning curves
# (figure_rl_curves: results/figures/<region>/rl_learning_curves.png). Needs the rl extra
# (pip install -e ".[rl]": PyTorch, stable-baselines3).

RL_ENV = "../envs/rl.yaml"
#: The code a PPO policy depends on beyond its task's (hashed into rl_train's params).
RL_CODE = code_version("oneocean.methods.ppo", "oneocean.sb3", "oneocean.envs",
                       "oneocean.evaluate")


if config["rl"]["enabled"]:

    localrules:
        table_task_success_rl,
        figure_rl_curves,
        manifest_rl,

    # One PPO policy per task: training seeds only (checked against rl_evaluation_seeds()).
    rule rl_train:
        conda:
            RL_ENV
        input:
            grid=rules.export_grid.output.npz,
            kernel=rules.compile_kernel.output.record,
        output:
            policy="results/rl/{region}/{variant}/{task}/policy.zip",
            report="results/rl/{region}/{variant}/{task}/training_report.json",
            prov="results/provenance/rl/{region}/{variant}/{task}/policy.json",
        log:
            "logs/rl/{region}/{variant}/{task}/train.log",
        benchmark:
            "results/benchmarks/rl/{region}/{variant}/{task}/train.tsv"
        params:
            rl=lambda wc: {k: config["rl"][k] for k in ("tiers_train", "budget_steps",
                                                        "n_envs", "seeds")},
            dynamics=lambda wc: config["rollouts"]["dynamics"],
            evaluation_seeds=lambda wc: rl_evaluation_seeds(),
            code=lambda wc: {"rl": RL_CODE, "task": task_code(wc.task)},
        threads: 1
        # no benchmark recorded: sized conservatively (PPO training budget)
        resources:
            mem_mb=4000,
            runtime=240,
        script:
            "../scripts/rl_train.py"

    # One PPO evaluation cell: the task's policy on the cell's episodes (evaluation seed).
    rule rl_cell:
        conda:
            RL_ENV
        input:
            grid=rules.export_grid.output.npz,
            policy=rules.rl_train.output.policy,
        output:
            parquet="results/rollouts/{region}/{variant}/{task}/tier{tier}/ppo.parquet",
            prov="results/provenance/rollouts/{region}/{variant}/{task}/tier{tier}/ppo.json",
        log:
            "logs/rollouts/{region}/{variant}/{task}/tier{tier}/ppo.log",
        benchmark:
            "results/benchmarks/rollouts/{region}/{variant}/{task}/tier{tier}/ppo.tsv"
        params:
            run=rl_run,
            code=lambda wc: {"rl": RL_CODE, "task": task_code(wc.task)},
        threads: 1
        # no benchmark recorded: sized conservatively
        resources:
            mem_mb=2000,
            runtime=30,
        script:
            "../scripts/rl_cell.py"

    # Table V over the RL tasks and tiers, with the PPO rows.
    rule table_task_success_rl:
        conda:
            PY_ENV
        input:
            cells=rl_table_cells(),
        output:
            **_table_rule_io("task_success_by_tier_rl"),
        log:
            "logs/tables/{region}/task_success_by_tier_rl.log",
        params:
            code=TABLES_CODE,
        threads: 1
        script:
            "../scripts/rl_table.py"

    # The learning curves of the trainings of rl.tasks (from their reports).
    rule figure_rl_curves:
        conda:
            PY_ENV
        input:
            reports=expand(rules.rl_train.output.report, region="{region}",
                           variant=config["rollouts"]["variant"], task=config["rl"]["tasks"]),
        output:
            **_figure_io("rl_learning_curves", "rl_learning_curves"),
        log:
            "logs/figures/{region}/rl_learning_curves.log",
        params:
            code=FIGURES_CODE,
        threads: 1
        script:
            "../scripts/figure_paper.py"

    # The stage's manifest: every rl artifact (weights included) by hash.
    rule manifest_rl:
        conda:
            PY_ENV
        input:
            rl_provenance(),
        output:
            "results/manifest/{region}.rl.json",
        log:
            "logs/manifest/{region}.rl.log",
        script:
            "../scripts/collect_manifest.py"

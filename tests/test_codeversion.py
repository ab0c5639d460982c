"""A rollout cell's code version covers its own task's files and the shared engine only."""

from pathlib import Path

import oneocean
from oneocean.pipeline.codeversion import files_hash, task_code, task_files, tasks_code

PKG = Path(oneocean.__file__).resolve().parent


def _names(task):
    return {f.relative_to(PKG).as_posix() for f in task_files(task)}


def test_a_task_depends_on_its_own_files_and_the_shared_engine_only():
    g2g = _names("G2G")
    assert {"tasks/g2g.py", "methods/heuristic/g2g.py", "data/tasks/G2G.yaml",
            "kernels/g2g.py", "tasks/loop.py", "engine/dynamics.py", "tasks/learned.py",
            "data/vehicles.yaml"} <= g2g
    assert not {"tasks/sk.py", "methods/heuristic/sk.py", "data/tasks/SK.yaml",
                "kernels/sk.py", "methods/llm/plan.py", "methods/bc/train.py",
                "reporting/tables.py"} & g2g
    assert "tasks/sk.py" in _names("SK")
    # the ten tasks share everything but their own four files
    shared = set.intersection(*(_names(t) for t in ("G2G", "SK", "SPC")))
    assert _names("G2G") - shared == {"tasks/g2g.py", "methods/heuristic/g2g.py",
                                      "kernels/g2g.py", "data/tasks/G2G.yaml"}
    # the sensor models and the route planner are shared; RF also imports G2G's task code
    assert {"sensing/kernels.py", "data/sensors.yaml", "tasks/routing.py"} <= shared
    # so are the task layer's shared modules and the methods' steering laws
    assert {"tasks/common.py", "tasks/tiers.py", "tasks/regime.py", "tasks/spawn.py",
            "tasks/waypoints.py", "methods/steering.py"} <= shared
    assert {"tasks/g2g.py", "methods/heuristic/g2g.py"} <= _names("RF")


def test_the_hash_follows_the_bytes(tmp_path):
    assert task_code("G2G") != task_code("SK")
    assert tasks_code(["G2G", "SK"]) == tasks_code(["SK", "G2G"])
    a, b = tmp_path / "a.py", tmp_path / "b.py"
    a.write_text("x = 1\n")
    b.write_text("y = 2\n")
    h = files_hash([a, b])
    assert files_hash([b, a]) == h
    b.write_text("y = 3\n")
    assert files_hash([a, b]) != h

"""A built wheel carries everything the package reads at run time: installed into a fresh
virtual environment (no network), it loads and validates the config, a tier table, the task
registry and the vehicles file without the source checkout."""

import json
import os
import shutil
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

from workflow_helpers import REPO

pytestmark = pytest.mark.slow

SCRIPT = textwrap.dedent("""\
    import sys
    from pathlib import Path

    import oneocean
    from oneocean import registry
    from oneocean.config import SCHEMA_PATH, load_config, validate_config
    from oneocean.engine import load_vehicle
    from oneocean.tasks.tiers import load_task_table

    prefix = Path(sys.prefix).resolve()
    assert Path(oneocean.__file__).resolve().is_relative_to(prefix), oneocean.__file__
    assert SCHEMA_PATH.resolve().is_relative_to(prefix), SCHEMA_PATH
    cfg = load_config(sys.argv[1])
    assert cfg["rollouts"]["tasks"] == list(registry.task_ids())[:10], cfg["rollouts"]["tasks"]
    assert validate_config({})["region"]["name"] == "synthetic_coast"
    table = load_task_table("FT")
    assert table["agents"]["range"] == [2, 10] and set(table["tiers"]) == {1, 2, 3}
    assert registry.task_spec("UPL").primary == "lift_success"
    vehicle = load_vehicle()
    assert vehicle.name == "remus100" and vehicle.spec and vehicle.params.size > 0
    assert vehicle.v_max == 2.5
    # every vehicle a tier table names is in the installed vehicles file
    for task in list(registry.task_ids())[:10]:
        name = load_task_table(task)["vehicle"]
        assert load_vehicle(name).name == name, (task, name)
    assert load_vehicle("bluerov2_heavy").v_max == 0.85
    print("OK", oneocean.__file__)
    """)


def _run(cmd, **kw):
    res = subprocess.run(cmd, capture_output=True, text=True, **kw)
    assert res.returncode == 0, f"{cmd}\n{res.stdout}\n{res.stderr}"
    return res


def _outer_path(inner_path: list[str]) -> list[str]:
    """The directories on this interpreter's ``sys.path`` a nested venv lacks (in order),
    without the checkout's: its site-packages, a venv's or the base's, a user site, dirs added
    by ``.pth`` files or PYTHONPATH, wherever this run finds its dependencies."""
    seen, out = set(inner_path), []
    for entry in sys.path:
        p = os.path.realpath(entry or ".")
        if p in seen or not os.path.isdir(p) or Path(p).is_relative_to(REPO):
            continue
        seen.add(p)
        out.append(p)
    return out


def _see_this_environment(py: Path, env: dict) -> None:
    """Let the venv of interpreter ``py`` import what this interpreter imports.

    ``venv --system-site-packages`` shows the *base* interpreter's packages, which is not
    this environment when the tests run inside a virtual environment (or find packages via
    ``.pth`` files or PYTHONPATH). A ``.pth`` file in the new venv appends this interpreter's
    path directories after the venv's own site-packages (so the wheel installed there wins;
    the listed directories' own ``.pth`` hooks, e.g. an editable oneocean, stay inactive).
    """
    probe = ("import json, os, sys, sysconfig; print(json.dumps([sysconfig.get_path('purelib'),"
             " [os.path.realpath(p or '.') for p in sys.path]]))")
    site_dir, inner = json.loads(_run([str(py), "-c", probe], env=env).stdout)
    Path(site_dir, "_outer_env.pth").write_text("\n".join(_outer_path(inner)) + "\n")


def test_wheel_installs_and_reads_its_package_data(tmp_path):
    # build from a copy of the sources, so the build leaves nothing in the checkout
    src = tmp_path / "src_copy"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, src / name)
    shutil.copytree(REPO / "src", src / "src", ignore=shutil.ignore_patterns(
        "__pycache__", "*.egg-info", "*.nbi", "*.nbc", "*.pyc"))
    wheels = tmp_path / "wheels"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
          "--no-index", "-q", "-w", str(wheels), str(src)])
    (wheel,) = wheels.glob("oneocean-*.whl")

    # every YAML/JSON file of the package's data folder is in the wheel
    data = REPO / "src" / "oneocean"
    wanted = {p.relative_to(data.parent).as_posix() for pat in ("*.yaml", "*.json")
              for p in (data / "data").rglob(pat)}
    assert "oneocean/data/config.schema.yaml" in wanted
    assert len([w for w in wanted if w.startswith("oneocean/data/tasks/")]) >= 10
    with zipfile.ZipFile(wheel) as zf:
        assert wanted <= set(zf.namelist()), wanted - set(zf.namelist())

    # a fresh venv: dependencies from this environment, oneocean from the wheel alone (no
    # PYTHONPATH that could point back at a source tree)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)])
    py = venv / "bin" / "python"
    _see_this_environment(py, env)
    _run([str(py), "-m", "pip", "install", "--no-deps", "--no-index", "--ignore-installed",
          "-q", str(wheel)], cwd=tmp_path, env=env)
    script = tmp_path / "check_install.py"
    script.write_text(SCRIPT)
    out = _run([str(py), str(script), str(REPO / "config" / "config.yaml")],
               cwd=tmp_path, env=env).stdout
    assert out.startswith("OK ")
    assert Path(out.split()[1]).resolve().is_relative_to(venv.resolve())
    assert not Path(out.split()[1]).resolve().is_relative_to(REPO)

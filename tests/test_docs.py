"""The documentation site: it builds with warnings as errors (every tutorial executing), its
links resolve offline, and its generated reference covers every config key, command-line
option and task with text.

The build runs on a copy of ``docs/`` in a temporary folder (``ONEOCEAN_REPO`` points the
configuration at this repository), so the generated reference pages and the build output are
written there, never into the checkout. Links are checked offline: Sphinx and MyST warn on
every internal link, cross-reference or heading anchor that does not resolve (an error under
``-W``), and the README's relative links are checked here; external URLs are not fetched.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
sys.path.insert(0, str(DOCS / "_ext"))

pytest.importorskip("sphinx")
pytest.importorskip("myst_nb")
pytest.importorskip("numpydoc")
pytest.importorskip("furo")

import oneocean_reference as ref  # noqa: E402  (docs/_ext)


def _copy_docs(dst: Path) -> Path:
    """A copy of ``docs/`` without anything a build writes."""
    shutil.copytree(DOCS, dst, ignore=shutil.ignore_patterns(
        "_build", "jupyter_execute", "reference", "__pycache__", ".ipynb_checkpoints"))
    return dst


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """Build the site once for this module: ``(html folder, seconds, output)``."""
    tmp = tmp_path_factory.mktemp("docs")
    src = _copy_docs(tmp / "docs")
    out = tmp / "html"
    env = {**os.environ, "ONEOCEAN_REPO": str(REPO)}
    env.pop("ONEOCEAN_DOCS_NO_EXECUTE", None)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html",
                           "-q", str(src), str(out)], capture_output=True, text=True,
                          env=env, cwd=tmp, timeout=3600)
    seconds = time.perf_counter() - t0
    return out, seconds, proc


def test_docs_build_without_warnings_and_run_every_tutorial(built, record_property):
    out, seconds, proc = built
    record_property("docs_build_seconds", round(seconds, 1))
    print(f"docs build (sphinx -W, tutorials executed): {seconds:.0f} s")
    problems = [line for line in (proc.stderr + proc.stdout).splitlines()
                if re.search(r": (WARNING|ERROR|CRITICAL): ", line)
                or line.startswith(("Traceback", "Exception", "sphinx.errors", "myst_nb"))]
    assert proc.returncode == 0, (
        f"sphinx -W failed (exit {proc.returncode}) after {seconds:.0f} s:\n"
        + "\n".join(problems[:60]) + "\n--- end of the output:\n"
        + (proc.stderr or proc.stdout)[-3000:])
    for page in ("index", "getting-started", "tutorials/index", "concepts/index", "results",
                 "benchmarks", "changelog", "reference/config", "reference/cli",
                 "reference/api/index", "contracts"):
        assert (out / f"{page}.html").is_file(), page
    # every tutorial was built, and executed: its code cells have outputs in the page
    tutorials = sorted(p.stem for p in (DOCS / "tutorials").glob("*.md") if p.stem != "index")
    for name in tutorials:
        html = (out / "tutorials" / f"{name}.html").read_text()
        assert "cell_output" in html, f"tutorial {name} shows no executed output"


def test_readme_relative_links_point_to_files_that_exist():
    """Every relative link and image of the README names a file of the repository (and a
    heading of it, for a Markdown file with an anchor); external URLs are not fetched."""
    text = (REPO / "README.md").read_text()
    links = re.findall(r"!?\[[^\]]*\]\(([^)\s]+)\)", text)
    assert links, "the README links nowhere"
    for link in links:
        if re.match(r"^[a-z][a-z0-9+.-]*:", link):      # http:, https:, mailto: ...
            continue
        path, _, anchor = link.partition("#")
        target = (REPO / path) if path else REPO / "README.md"
        assert target.exists(), f"README links to {link}: {target} does not exist"
        if anchor and target.suffix == ".md":
            slugs = {_slug(h) for h in re.findall(r"^#+\s+(.*)$", target.read_text(), re.M)}
            assert anchor in slugs, f"README links to {link}: no such heading"


def _slug(heading: str) -> str:
    """GitHub's (and MyST's) anchor of a heading."""
    s = re.sub(r"[^\w\- ]", "", heading.strip().lower().replace("`", ""))
    return s.replace(" ", "-")


def test_every_config_key_has_a_description_and_a_default():
    rows = ref.config_rows()
    assert len(rows) > 100
    missing = [r["key"] for r in rows if not r["description"]]
    assert not missing, f"config keys without a description in the schema: {missing}"
    # list items' keys (llm.models[].name) are given by the user; every other key has a default
    no_default = [r["key"] for r in rows if not r["has_default"] and "[]." not in r["key"]]
    assert not no_default, f"config keys without a default in the schema: {no_default}"


def test_every_cli_option_has_help():
    rows = ref.cli_rows()
    commands = ref.cli_commands()
    assert {c for c, _ in commands} >= {"verify", "evaluate", "ladder-readme"}
    assert all(h for _, h in commands), commands
    missing = [f"oneocean {r['command']} {r['option']}" for r in rows if not r["help"]]
    assert not missing, f"command-line options without help: {missing}"


def test_every_task_has_its_page_and_spec_text():
    from oneocean import registry

    pages = ref.task_pages()
    assert list(pages) == list(registry.task_ids())
    for tid, p in pages.items():
        assert len(p["description"]) > 80, f"{tid}: its tier table has no description comment"
        bare = [k for k in p["harder"] if not p["comments"].get(k)]
        assert not bare, f"{tid}: stressors without a comment in the tier table: {bare}"
        for tier in p["table"]["tiers"].values():
            for key in tier:
                assert f"| `{key}` |" in p["page"], (tid, key)


def test_generated_reference_covers_every_key_option_task_and_module(tmp_path):
    out = ref.generate(tmp_path / "reference")
    config = (out / "config.md").read_text()
    for r in ref.config_rows():
        assert f"`{r['key']}`" in config, r["key"]
    cli = (out / "cli.md").read_text()
    for r in ref.cli_rows():
        assert f"`{r['option']}`" in cli, r
    from oneocean import registry
    for tid in registry.task_ids():
        assert (out / "tasks" / f"{tid}.md").is_file(), tid
        assert f"<{tid}>" in (out / "tasks" / "index.md").read_text(), tid
    pages = {p.stem for p in (out / "api").glob("*.rst")}
    assert pages == set(ref.public_modules())
    # the docstring checker and the API pages agree on what is public
    sys.path.insert(0, str(REPO / "tests"))
    from docstring_check import SRC, public_modules
    files = {".".join(p.relative_to(SRC.parent).with_suffix("").parts).removesuffix(".__init__")
             for p in public_modules()}
    assert files == pages

"""LaTeX: wide tables shrink to the line width, tables compile on their own, the paper
build's errors are one line. The pdflatex tests skip where TeX is not installed, except in CI
(ONEOCEAN_REQUIRE_TEX=1, set by .ci/run after it installs Debian's TeX packages), where a
missing TeX is a failure."""

import pandas as pd
import pytest

from oneocean.reporting import latex
from oneocean.errors import ConfigError
from oneocean.reporting.latex import booktabs as _latex, fit_width
from oneocean.reporting.tables import to_booktabs
from workflow_helpers import need_tex as _need_tex


def test_fit_width_boxes_the_tabular_once():
    tex = _latex(["A", "B"], [["1", "2"]], "cap", "tab:x")
    assert tex.count("\\setbox0=\\hbox{\\begin{tabular}") == 1
    assert "\\ifdim\\wd0>\\linewidth\\resizebox{\\linewidth}{!}{\\box0}\\else\\mbox{\\box0}\\fi" in tex
    assert tex.index("\\caption{cap}") < tex.index("\\setbox0") < tex.index("\\end{table}")
    # pandas' booktabs writer goes through it too
    assert "\\setbox0=\\hbox{" in to_booktabs(pd.DataFrame({"a": [1.0]}), "c", "tab:y")
    assert fit_width("no table") == "no table"


def test_missing_tex_is_a_one_line_error(tmp_path, monkeypatch):
    tex = tmp_path / "t.tex"
    tex.write_text("\\documentclass{article}\\begin{document}x\\end{document}\n")
    monkeypatch.setattr(latex.shutil, "which", lambda prog: None)
    with pytest.raises(ConfigError, match=r"^latexmk not found: .*apt-get install latexmk"):
        latex.compile_pdf(tex, tmp_path / "t.pdf")
    assert not (tmp_path / "t.pdf").exists()
    with pytest.raises(ConfigError, match=r"^LaTeX engine 'xelatex' unknown: latexmk or pdflatex"):
        latex.compile_pdf(tex, tmp_path / "t.pdf", engine="xelatex")
    assert not (tmp_path / "t.pdf").exists()


def _wide_and_narrow(tmp_path):
    wide = _latex([f"Column {i}" for i in range(14)],
                  [[f"{i}.0 [{i}.0, {i + 1}.0]" for i in range(14)]], "Wide", "tab:wide",
                  wide=True)
    narrow = _latex(["Task", "SR (\\%)"], [["G2G", "\\textbf{100.0}"]], "Narrow", "tab:n")
    (tmp_path / "wide.tex").write_text(wide)
    (tmp_path / "narrow.tex").write_text(narrow)
    return tmp_path / "wide.tex", tmp_path / "narrow.tex"


def test_generated_tables_compile_standalone_and_fit(tmp_path):
    _need_tex("pdflatex")
    for table in _wide_and_narrow(tmp_path):
        doc = tmp_path / f"{table.stem}_doc.tex"
        doc.write_text(latex.standalone_table(table))
        pdf = latex.compile_pdf(doc, tmp_path / f"{table.stem}.pdf", engine="pdflatex",
                                log_path=tmp_path / f"{table.stem}.log")
        assert pdf.read_bytes().startswith(b"%PDF")
        log = (tmp_path / f"{table.stem}.log").read_text()
        assert "Overfull \\hbox" not in log, table.stem       # the wide one was shrunk


def test_a_latex_error_names_the_file_and_leaves_no_pdf(tmp_path):
    _need_tex("pdflatex")
    bad = tmp_path / "bad.tex"
    bad.write_text("\\documentclass{article}\\begin{document}\\undefinedmacro\\end{document}\n")
    with pytest.raises(ConfigError, match=r"bad\.tex: LaTeX failed: Undefined control sequence"):
        latex.compile_pdf(bad, tmp_path / "bad.pdf", engine="pdflatex")
    assert not (tmp_path / "bad.pdf").exists()


def test_pdf_bytes_are_reproducible(tmp_path):
    """Same source, built twice, with its included figure at two different absolute paths
    (as two runs in two folders): the same PDF bytes (fixed date and id, no file names)."""
    _need_tex("latexmk")
    doc = tmp_path / "d.tex"
    doc.write_text("\\documentclass{article}\\begin{document}OneOcean\\end{document}\n")
    fig = latex.compile_pdf(doc, tmp_path / "fig.pdf").read_bytes()
    out = []
    for run in ("run_a", "run_b"):
        (tmp_path / run).mkdir()
        (tmp_path / run / "fig.pdf").write_bytes(fig)
        main = tmp_path / run / "main.tex"
        main.write_text("\\documentclass{article}\\usepackage{graphicx}\\begin{document}"
                        f"\\includegraphics{{{(tmp_path / run / 'fig.pdf').as_posix()}}}"
                        "\\end{document}\n")
        out.append(latex.compile_pdf(main, tmp_path / run / "out.pdf").read_bytes())
    assert out[0] == out[1] and out[0].startswith(b"%PDF")
    assert b"run_a" not in out[0]

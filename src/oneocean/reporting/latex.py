"""LaTeX: the booktabs writer of the generated tables, and compiling the paper and tables.

:func:`booktabs` writes every generated table (shrunk to the line width when wider:
:func:`fit_width`); :func:`build_paper`, :func:`standalone_table` and :func:`compile_pdf`
compile the paper (``paper/main.tex``) and tables on their own.

TeX is optional: nothing in the default workflow needs it. The ``paper`` target and the table
tests call :func:`compile_pdf`, which names the missing program in a one-line error when
``latexmk``/``pdflatex`` is not installed (Debian: ``latexmk texlive-latex-base
texlive-latex-recommended texlive-fonts-recommended``).

PDFs are byte-reproducible: the build runs in a temporary folder under fixed file names with
``SOURCE_DATE_EPOCH``/``FORCE_SOURCE_DATE`` set, so pdfTeX writes a fixed date and document
id, and without pdfTeX's file-name records of included figures (their absolute paths); the
PDF is renamed onto its path only when the build succeeded.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from ..errors import ConfigError
from ..io import write_bytes_atomic

#: Debian packages that provide what the generated LaTeX needs.
DEBIAN_TEX = ("latexmk", "texlive-latex-base", "texlive-latex-recommended",
              "texlive-fonts-recommended")


def _need(program: str) -> str:
    path = shutil.which(program)
    if path is None:
        raise ConfigError(f"{program} not found: the PDF needs a TeX installation (Debian: "
                          f"apt-get install {' '.join(DEBIAN_TEX)})")
    return path


def compile_pdf(tex_path, out_pdf, *, pretex: str = "", log_path=None,
                engine: str = "latexmk") -> Path:
    """Compile ``tex_path`` to ``out_pdf`` (atomically, byte-reproducibly).

    Parameters
    ----------
    tex_path : path-like
        The ``.tex`` file; its inputs are found relative to its own folder.
    out_pdf : path-like
        The output PDF.
    pretex : str, default ""
        TeX code run first (e.g. ``\\def\\region{...}``).
    log_path : path-like, optional
        Where to write the full TeX log.
    engine : {"latexmk", "pdflatex"}, default "latexmk"
        ``latexmk`` (``latexmk -pdf``) or ``pdflatex`` (a single pass).

    Returns
    -------
    pathlib.Path
        ``out_pdf``.

    Raises
    ------
    ConfigError
        One line, if ``engine`` is unknown, ``tex_path`` does not exist, the TeX program is
        not installed, or LaTeX fails (naming the file and the first error line).
    """
    if engine not in ("latexmk", "pdflatex"):
        raise ConfigError(f"LaTeX engine {engine!r} unknown: latexmk or pdflatex")
    tex_path = Path(tex_path).resolve()
    if not tex_path.is_file():
        raise ConfigError(f"{tex_path}: no such LaTeX file")
    env = {**os.environ, "SOURCE_DATE_EPOCH": "0", "FORCE_SOURCE_DATE": "1"}
    # no /PTEX.FileName etc.: included figures' absolute paths would end up in the bytes
    pretex = "\\ifdefined\\pdfsuppressptexinfo\\pdfsuppressptexinfo=-1\\fi" + pretex
    with tempfile.TemporaryDirectory(prefix="oneocean-tex-") as tmp:
        shutil.copyfile(tex_path, Path(tmp) / "main.tex")
        if engine == "latexmk":
            cmd = [_need("latexmk"), "-pdf", "-interaction=nonstopmode", "-halt-on-error",
                   "-quiet"]
            cmd += [f"-usepretex={pretex}", "main.tex"]
        else:
            cmd = [_need("pdflatex"), "-interaction=nonstopmode", "-halt-on-error",
                   pretex + "\\input{main.tex}"]
        # inputs are found relative to the .tex file's own folder, as in a hand build there
        env["TEXINPUTS"] = f"{tex_path.parent}{os.pathsep}" + env.get("TEXINPUTS", "")
        proc = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True)
        log = Path(tmp) / "main.log"
        text = log.read_text(errors="replace") if log.is_file() else proc.stdout + proc.stderr
        if log_path is not None:
            Path(log_path).parent.mkdir(parents=True, exist_ok=True)
            Path(log_path).write_text(text)
        pdf = Path(tmp) / "main.pdf"
        if proc.returncode != 0 or not pdf.is_file():
            first = next((ln for ln in text.splitlines() if ln.startswith("!")),
                         f"exit code {proc.returncode}")
            raise ConfigError(f"{tex_path}: LaTeX failed: {first.lstrip('! ').strip()}")
        write_bytes_atomic(out_pdf, pdf.read_bytes())
    return Path(out_pdf)


def standalone_table(table_tex) -> str:
    """A minimal document around one generated table, for compiling it on its own.

    Parameters
    ----------
    table_tex : path-like
        The table's ``.tex`` file (input by its absolute path).

    Returns
    -------
    str
        LaTeX source of an ``article`` loading the packages the tables need
        (:data:`LATEX_PACKAGES`).
    """

    path = Path(table_tex).resolve()
    return ("\\documentclass{article}\n\\usepackage[margin=2cm]{geometry}\n"
            + "".join(f"\\usepackage{{{p}}}\n" for p in LATEX_PACKAGES)
            + f"\\begin{{document}}\n\\input{{{path.as_posix()}}}\n\\end{{document}}\n")


def build_paper(tex_path, out_pdf, region: str, results_dir, log_path=None) -> Path:
    """Compile the paper with ``\\region`` and ``\\resultsdir`` set to a region and results folder.

    Parameters
    ----------
    tex_path : path-like
        The paper source (``paper/main.tex``).
    out_pdf : path-like
        The output PDF.
    region : str
        The region name, defined as ``\\region``.
    results_dir : path-like
        The results folder, defined as ``\\resultsdir`` (absolute).
    log_path : path-like, optional
        Where to write the full TeX log.

    Returns
    -------
    pathlib.Path
        ``out_pdf``.

    Raises
    ------
    ConfigError
        As :func:`compile_pdf`.
    """
    results = Path(results_dir).resolve().as_posix()
    return compile_pdf(tex_path, out_pdf, log_path=log_path,
                       pretex=f"\\def\\region{{{region}}}\\def\\resultsdir{{{results}}}")


#: LaTeX packages every generated table needs (``\\usepackage{...}`` in the document).
LATEX_PACKAGES = ("booktabs", "graphicx", "amssymb")


def fit_width(tex: str) -> str:
    """Shrink the tabular of a table to the line width when (and only when) it is wider.

    The tabular is set in a box, measured, and scaled with graphicx's ``\\resizebox`` if it
    does not fit (plain LaTeX, no extra package); a narrow table is left at its size.

    Parameters
    ----------
    tex : str
        LaTeX with one ``tabular`` environment (only the first is wrapped).

    Returns
    -------
    str
        The same LaTeX with the tabular wrapped in the measuring box.
    """
    return (tex.replace("\\begin{tabular}", "\\begingroup\\setbox0=\\hbox{\\begin{tabular}", 1)
            .replace("\\end{tabular}", "\\end{tabular}}%\n\\ifdim\\wd0>\\linewidth"
                     "\\resizebox{\\linewidth}{!}{\\box0}\\else\\mbox{\\box0}\\fi\\endgroup", 1))


def booktabs(header: list[str], rows: list, caption: str, label: str, *, align: str = "",
           wide: bool = False) -> str:
    """A booktabs table, shrunk to the line width when wider (:func:`fit_width`).

    Parameters
    ----------
    header : list of str
        Column headings (LaTeX).
    rows : list
        Rows: a list of cell texts, ``("group", text)`` a family heading spanning the table,
        ``("rule",)`` a midrule.
    caption, label : str
        The table's caption and ``\\label``.
    align : str, optional
        The tabular's column spec (default ``l`` then ``r`` per further column).
    wide : bool, default False
        A ``table*`` in ``\\scriptsize`` with narrow column gaps (spans both columns).

    Returns
    -------
    str
        The table's LaTeX.
    """
    env = "table*" if wide else "table"
    lines = [f"\\begin{{{env}}}[t]", "\\centering", "\\scriptsize" if wide else "\\small"]
    if wide:
        lines.append("\\setlength{\\tabcolsep}{3pt}")
    lines += [f"\\caption{{{caption}}}", f"\\label{{{label}}}",
              "\\begin{tabular}{" + (align or "l" + "r" * (len(header) - 1)) + "}",
              "\\toprule", " & ".join(header) + " \\\\", "\\midrule"]
    for r in rows:
        if isinstance(r, tuple) and r[0] == "group":
            lines.append(f"\\multicolumn{{{len(header)}}}{{l}}{{\\emph{{{r[1]}}}}} \\\\")
        elif isinstance(r, tuple) and r[0] == "rule":
            lines.append("\\midrule")
        else:
            lines.append(" & ".join(r) + " \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", f"\\end{{{env}}}", ""]
    return fit_width("\n".join(lines))

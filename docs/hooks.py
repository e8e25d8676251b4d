"""MkDocs hooks of jaxppo's site (mkdocs.yml: ``hooks``).

* Executed tutorials: a page whose Markdown holds ``<!-- execute -->`` has
  its ```` ```python ```` blocks run in order, as one script, from the
  repository root (matplotlib's Agg backend). Below each block the page
  shows what it printed and the figures it left open, and at the top how
  long the whole page took. Results are cached in ``.docs_exec/`` under a
  key made of the page's text, this file, every file of the package (code
  and data) and the library versions, so a build right after the test
  suite (``tests/test_examples.py`` runs the same pages through
  ``execute_page`` and fills the cache) does not run them twice, and a
  changed page, package or library runs them again. The build runs a page
  in a fresh Python process (a long-running ``mkdocs serve`` holds the old
  package imported).
* The CLI reference: ``<!-- cli-help -->`` becomes the ``--help`` of
  ``jaxppo`` and of every subcommand, from the argparse parser itself.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import os
import re
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / ".docs_exec"
EXECUTE = "<!-- execute -->"
CLI_HELP = "<!-- cli-help -->"
BLOCK = re.compile(r"```python\n(.*?)```", re.S)

_results: dict = {}


def _key(text: str, root: Path = ROOT) -> str:
    """The cache key of a page: its text, this file, every file of the
    package (code and bundled data) and the versions of the libraries that
    compute and draw."""
    import importlib.metadata as md

    h = hashlib.sha256(text.encode())
    h.update(Path(__file__).read_bytes())
    for path in sorted((root / "jaxppo").rglob("*")):
        if path.is_file() and "__pycache__" not in path.parts:
            h.update(str(path.relative_to(root)).encode())
            h.update(path.read_bytes())
    for lib in ("jax", "jaxlib", "numpy", "numpyro", "optimistix", "equinox", "matplotlib", "astropy"):
        try:
            h.update(f"{lib}={md.version(lib)}".encode())
        except md.PackageNotFoundError:
            h.update(f"{lib}=none".encode())
    return h.hexdigest()[:20]


def execute_page(page: str, root: Path = ROOT, cache: Path = CACHE, force: bool = False,
                 fresh_process: bool = False):
    """Run the Python blocks of ``docs/<page>`` in order as one script from
    ``root`` and store what each printed (stdout and stderr, warnings
    included) and the figures it left open in ``cache/<page stem>-<key>/``;
    output folders named ``out="NAME"`` in the code are put in that folder
    too. Returns (result, namespace): result = {"key", "seconds", "blocks":
    [{"stdout", "figures": [file names]}]}; namespace is the script's
    globals, None when the cache answered or the page ran in another
    process (``force``: run even when cached, as the tests do;
    ``fresh_process``: run in a new Python process, as the site build does,
    so that a long-running ``mkdocs serve`` never shows what an edited
    package's already imported old code printed)."""
    text = (root / "docs" / page).read_text()
    key = _key(text, root)
    folder = cache / f"{Path(page).stem}-{key}"
    done = folder / "result.json"
    if done.is_file() and not force:
        return json.loads(done.read_text()), None
    if fresh_process:
        import subprocess
        import sys

        code = ("import importlib.util, sys; spec = importlib.util.spec_from_file_location('h', sys.argv[1]); "
                "h = importlib.util.module_from_spec(spec); spec.loader.exec_module(h); "
                "h.execute_page(sys.argv[2], h.Path(sys.argv[3]), h.Path(sys.argv[4]), force=True)")
        subprocess.run([sys.executable, "-c", code, __file__, page, str(root), str(cache)], check=True)
        return json.loads(done.read_text()), None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    done.unlink(missing_ok=True)
    namespace: dict = {"__name__": "__docs__"}
    blocks = []
    cwd = os.getcwd()
    t0 = time.perf_counter()
    plt.close("all")
    try:
        os.chdir(root)
        for i, code in enumerate(BLOCK.findall(text)):
            code = re.sub(r"out=([\"'])([^\"'/]+)\1", lambda m: f"out={str(folder / m.group(2))!r}", code)
            out = io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out), warnings.catch_warnings():
                warnings.simplefilter("always")
                warnings.showwarning = lambda msg, cat, fn, ln, file=None, line=None: out.write(
                    f"{cat.__name__}: {msg}\n")
                exec(compile(code, f"docs/{page} (block {i + 1})", "exec"), namespace)
            figs = []
            for k, num in enumerate(plt.get_fignums()):
                name = f"block{i + 1}-fig{k + 1}.png"
                plt.figure(num).savefig(folder / name, dpi=90)
                figs.append(name)
            plt.close("all")
            blocks.append({"stdout": out.getvalue(), "figures": figs})
    finally:
        os.chdir(cwd)
    result = {"key": key, "seconds": time.perf_counter() - t0, "blocks": blocks}
    done.write_text(json.dumps(result))
    return result, namespace


def _rendered(markdown: str, page: str, result: dict) -> str:
    """The page with each block's output and figures below it."""
    stem = Path(page).stem
    pieces, last = [], 0
    for i, m in enumerate(BLOCK.finditer(markdown)):
        pieces.append(markdown[last:m.end()])
        last = m.end()
        b = result["blocks"][i]
        if b["stdout"].strip():
            pieces.append("\n\n```text\n" + b["stdout"].rstrip() + "\n```\n")
        for name in b["figures"]:
            pieces.append(f"\n![{stem}: block {i + 1}](exec-{stem}/{name})\n")
    pieces.append(markdown[last:])
    note = (f"\n!!! note \"Executed\"\n    The code on this page was run, as one script, for this page's text "
            f"and the package as they are in this build (in {result['seconds']:.0f} s on the machine that "
            "built the site); below each block is what it printed, warnings included, and the figures it "
            "drew.\n")
    return "".join(pieces).replace(EXECUTE, note, 1)


def on_files(files, config):
    from mkdocs.structure.files import File

    for f in list(files.documentation_pages()):
        text = Path(f.abs_src_path).read_text()
        if EXECUTE not in text:
            continue
        result, _ = execute_page(f.src_uri, fresh_process=True)
        _results[f.src_uri] = result
        folder = CACHE / f"{Path(f.src_uri).stem}-{result['key']}"
        base = str(Path(f.src_uri).parent / f"exec-{Path(f.src_uri).stem}").lstrip("./")
        for b in result["blocks"]:
            for name in b["figures"]:
                files.append(File.generated(config, f"{base}/{name}", abs_src_path=str(folder / name)))
    return files


def _cli_help() -> str:
    from jaxppo.cli import build_parser

    parser = build_parser()
    parts = ["## jaxppo\n", "```text\n" + parser.format_help().rstrip() + "\n```\n"]
    for action in parser._actions:  # argparse keeps its subcommands here
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                parts += [f"## jaxppo {name}\n", "```text\n" + sub.format_help().rstrip() + "\n```\n"]
    return "\n".join(parts)


def on_page_markdown(markdown: str, page, config, files) -> str:
    src = page.file.src_uri
    if src in _results:
        markdown = _rendered(markdown, src, _results[src])
    if CLI_HELP in markdown:
        markdown = markdown.replace(CLI_HELP, _cli_help())
    return markdown

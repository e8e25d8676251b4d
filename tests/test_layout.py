"""The package's layout stays what the README says: imports point down
(import-linter's contracts in pyproject.toml, run by .ci/run, and an
independent AST check here), private means private, no module of JAX's
internals, no module over 600 lines and no function over 80."""

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "jaxppo"
LAYERS = ("core", "model", ("inference", "activity"), "obliquity", "cli")
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80
# functions allowed past MAX_FUNCTION_LINES, each with the reason (none today)
LONG_FUNCTIONS: dict[str, str] = {}


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        yield path, parts, ast.parse(path.read_text())


def _layer(parts):
    if len(parts) < 2:
        return None
    for i, layer in enumerate(LAYERS):
        names = layer if isinstance(layer, tuple) else (layer,)
        if parts[1] in names:
            return i
    return None


def test_no_private_names_across_modules():
    bad = []
    for path, parts, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith("jaxppo")):
                for alias in node.names:
                    if alias.name.startswith("_") and alias.name != "__version__" and not alias.name.startswith("__"):
                        bad.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} imports {alias.name}")
    assert not bad, "\n".join(bad)


def test_no_jax_internals():
    bad = []
    for path, _, tree in _modules():
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            bad += [f"{path.relative_to(PACKAGE.parent)}:{node.lineno} {n}" for n in names if n.startswith("jax._src")]
    assert not bad, bad


def test_imports_point_down():
    """Each module imports only its own layer or lower ones; inference and
    activity not each other (import-linter checks the same in CI)."""
    bad = []
    for path, parts, tree in _modules():
        mine = _layer(parts)
        if mine is None:
            continue
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                here = parts if path.name == "__init__.py" else parts[:-1]
                target = here[: len(here) - node.level + 1] + (node.module.split(".") if node.module else [])
            elif (node.module or "").startswith("jaxppo"):
                target = node.module.split(".")
            else:
                continue
            theirs = _layer(target)
            if theirs is None:
                if target == ["jaxppo"] and parts[1] != "cli":  # the CLI sits above the package's API
                    bad.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} imports the package root")
                continue
            if theirs > mine or (theirs == mine and target[1] != parts[1]):
                bad.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} imports {'.'.join(target)}")
    assert not bad, "\n".join(bad)


def _docstring_lines(tree) -> set:
    """The line numbers of every module, class and function docstring."""
    lines = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
                lines.update(range(first.lineno, first.end_lineno + 1))
    return lines


def _code_lines(node, doc: set) -> int:
    """Lines of a function, less its (and its nested) docstrings."""
    return node.end_lineno - node.lineno + 1 - len([i for i in doc if node.lineno <= i <= node.end_lineno])


def test_sizes():
    """Sizes count code, not docstrings: the docstrings are the API
    reference's source (tests/test_docstrings.py asks for parameters,
    returns, raises and examples), and documenting a function must not
    force it apart."""
    bad = []
    for path, _, tree in _modules():
        doc = _docstring_lines(tree)
        n = path.read_text().count("\n") - len(doc)
        rel = str(path.relative_to(PACKAGE.parent))
        if n > MAX_MODULE_LINES:
            bad.append(f"{rel}: {n} lines of code")
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = _code_lines(node, doc)
                if length > MAX_FUNCTION_LINES and f"{rel}:{node.name}" not in LONG_FUNCTIONS:
                    bad.append(f"{rel}:{node.name}: {length} lines")
    assert not bad, "\n".join(bad)


def test_the_checks_can_fail(tmp_path, monkeypatch):
    """The AST checks see what they look for (a module importing a private
    name, jax._src and an upward import)."""
    pkg = tmp_path / "jaxppo"
    (pkg / "model").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "model" / "__init__.py").write_text("")
    (pkg / "model" / "_a.py").write_text("from ._b import _hidden\nfrom jax._src import core\n"
                                        "from ..obliquity._scan import run_scan\n")
    monkeypatch.setattr(__import__(__name__), "PACKAGE", pkg)
    for check in (test_no_private_names_across_modules, test_no_jax_internals, test_imports_point_down):
        with pytest.raises(AssertionError):
            check()


def test_sizes_count_code_not_docstrings():
    """The size rule's counter: a function of 90 docstring lines and 3 code
    lines counts 3 + its def line; 90 code lines count 90 + 1."""
    doc = '    """' + "\n".join(["x"] * 90) + '"""\n'
    src = "def f(a):\n" + doc + "    b = a\n    c = b\n    return c\n\n\ndef g(a):\n" + "    a = a\n" * 90
    tree = ast.parse(src)
    lines = _docstring_lines(tree)
    f, g = tree.body
    assert _code_lines(f, lines) == 4
    assert _code_lines(g, lines) == 91


def _scan_timings(root: Path) -> tuple[str, str]:
    """(first run, second run) [s] of the default scan in docs/timings.md,
    the table benchmarks/timings.py writes."""
    import re

    rows = (root / "docs" / "timings.md").read_text().splitlines()
    first = [r for r in rows if r.startswith("| `jaxppo scan`") and "first run" in r]
    second = [r for r in rows if r.startswith("| `jaxppo scan`") and "second run" in r]
    assert len(first) == len(second) == 1
    return tuple(re.split(r"\s*\|\s*", r)[2] for r in (first[0], second[0]))


def _quoted_scan_times(text: str) -> list[tuple[str, str]]:
    """(seconds as written, "first" | "later") for every time quoted just
    before "the first time / first run" or "later runs / afterwards / the next"."""
    import re

    out = []
    for m in re.finditer(r"(\d+(?:\.\d+)?(?:-\d+(?:\.\d+)?)?) s\b", text):
        after = " ".join(text[m.end():m.end() + 70].split())
        if re.match(r"[^.;]{0,25}(later runs|afterwards|for the next)", after):
            out.append((m.group(1), "later"))
        elif re.search(r"first (time|run)", after):
            out.append((m.group(1), "first"))
    return out


def test_docs_quote_the_generated_scan_timings():
    """Issue 24 (item 12, "one place that states the timings"): README and
    docs quoted the default scan's first run four ways (7-9 s, 9-10 s,
    ~10 s, 6.5-9.0 s) beside the generated table's 8.8 s. Every quote of a
    first or later run of the default scan is now the table's number."""
    root = Path(__file__).resolve().parents[1]
    first, second = _scan_timings(root)
    seen = 0
    for path in [root / "README.md", *sorted((root / "docs").glob("*.md"))]:
        if path.name == "timings.md":
            continue
        for quoted, which in _quoted_scan_times(path.read_text()):
            want = first if which == "first" else second
            assert quoted == want, f"{path.name}: {quoted} s for the {which} run; docs/timings.md says {want} s"
            seen += 1
    assert seen >= 8  # README, getting-started, cli, tutorial, scan: first and later runs
    # docs/api.md's jp.fit timing ("~1.3 s warm" against a measured 3.4-3.6 s)
    import re

    rows = (root / "docs" / "timings.md").read_text().splitlines()
    cold = [re.split(r"\s*\|\s*", r)[2] for r in rows if r.startswith("| `jp.fit`") and "cold" in r]
    warm = [re.split(r"\s*\|\s*", r)[2] for r in rows if r.startswith("| `jp.fit`") and "warm" in r]
    assert len(cold) == len(warm) == 1
    assert f"{cold[0]} s cold, {warm[0]} s warm" in " ".join((root / "docs" / "api.md").read_text().split())


def test_quoted_times_are_found():
    """The reader of the test above sees the phrasings the docs used."""
    text = ("figures in 7-9 s on this 2-core machine the first time (mostly compilation) and 5.5-6.5 s on "
            "later runs; compilation: 9-10 s for the first run on this machine, 5-6 s for the next")
    assert _quoted_scan_times(text) == [("7-9", "first"), ("5.5-6.5", "later"), ("9-10", "first"),
                                        ("5-6", "later")]

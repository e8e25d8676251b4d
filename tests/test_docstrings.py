"""Every name of the public API (``jaxppo.__all__``, ``jaxppo.activity.__all__``)
has a NumPy-style docstring: a summary line; ``Parameters`` when it takes
any; ``Returns`` (functions) or ``Attributes`` / ``Parameters`` (classes);
``Raises`` when its own code raises; ``Examples`` with doctest lines, and
those examples run (with float64 enabled) and print what they say. Public
methods and properties of the public classes have docstrings too, with
``Parameters`` when they take arguments. This is the API reference's
source (docs/reference/), so a name without it is a hole in the site."""

import doctest
import inspect
import re
import textwrap

import jax
import numpy as np
import pytest

import jaxppo as jp

jax.config.update("jax_enable_x64", True)

CONSTANTS = {"__version__", "activity", "KEPLER20_SPOT_CONTRAST", "PAPER_ROTATION_PERIOD"}
# the constants' docstrings are attribute docstrings (the string after the
# assignment), which the reference renders: test_constants_documented


def _public():
    out = [(f"jaxppo.{n}", getattr(jp, n)) for n in jp.__all__ if n not in CONSTANTS]
    out += [(f"jaxppo.activity.{n}", getattr(jp.activity, n)) for n in jp.activity.__all__ if n not in CONSTANTS]
    return out


PUBLIC = _public()
IDS = [n for n, _ in PUBLIC]


def _sections(doc: str) -> set:
    return set(re.findall(r"^([A-Z][A-Za-z ]+)\n-{3,}\s*$", doc, re.M))


def _own_params(obj) -> list:
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return []
    return [p for p in sig.parameters.values() if p.name not in ("self", "cls")
            and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]


def _raises(obj) -> bool:
    try:
        src = textwrap.dedent(inspect.getsource(obj))
    except (OSError, TypeError):
        return False
    # the function's own body, not nested docstrings: a raise statement
    return re.search(r"^\s+raise \w", src, re.M) is not None


def _members(cls):
    """Public methods and properties defined by the class itself."""
    for name, val in vars(cls).items():
        if name.startswith("_"):
            continue
        if isinstance(val, property) or inspect.isfunction(val) or isinstance(val, (staticmethod, classmethod)):
            yield name, val


@pytest.mark.parametrize("name,obj", PUBLIC, ids=IDS)
def test_numpy_docstring(name, obj):
    doc = inspect.getdoc(obj) or ""
    assert doc.strip(), f"{name}: no docstring"
    secs = _sections(doc)
    missing = []
    if inspect.isclass(obj):
        if _own_params(obj) and not ({"Parameters", "Attributes"} & secs):
            missing.append("Parameters or Attributes")
    else:
        if _own_params(obj) and "Parameters" not in secs:
            missing.append("Parameters")
        if "Returns" not in secs and "Yields" not in secs:
            missing.append("Returns")
        if _raises(obj) and "Raises" not in secs:
            missing.append("Raises")
    if "Examples" not in secs or ">>>" not in doc:
        missing.append("Examples (with >>> lines)")
    assert not missing, f"{name}: docstring lacks {', '.join(missing)} (sections found: {sorted(secs)})"


@pytest.mark.parametrize("name,obj", [(n, o) for n, o in PUBLIC if inspect.isclass(o)],
                         ids=[n for n, o in PUBLIC if inspect.isclass(o)])
def test_public_members_documented(name, obj):
    bad = []
    for mname, val in _members(obj):
        fn = val.fget if isinstance(val, property) else getattr(val, "__func__", val)
        doc = inspect.getdoc(fn) or ""
        if not doc.strip():
            bad.append(f"{mname}: no docstring")
        elif not isinstance(val, property) and _own_params(fn) and "Parameters" not in _sections(doc):
            bad.append(f"{mname}: no Parameters section")
    assert not bad, f"{name}: " + "; ".join(bad)


@pytest.mark.parametrize("name,obj", PUBLIC, ids=IDS)
def test_examples_run(name, obj, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # examples that write files write them here
    # a class's own methods and properties too (their examples are the
    # reference's); recurse stays inside the object's module
    finder = doctest.DocTestFinder(recurse=inspect.isclass(obj))
    tests = [t for t in finder.find(obj, name, globs={"jp": jp, "np": np, "jax": jax}) if t.examples]
    assert tests, f"{name}: no runnable example"
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for t in tests:
        runner.run(t)
    res = runner.summarize(verbose=False)
    assert res.failed == 0, f"{name}: {res.failed} of {res.attempted} example lines failed (run pytest -s to see them)"


@pytest.mark.parametrize("module,name", [("jaxppo.activity._spots", "KEPLER20_SPOT_CONTRAST"),
                                         ("jaxppo.activity._rotation", "PAPER_ROTATION_PERIOD")])
def test_constants_documented(module, name):
    """A public constant has an attribute docstring (the string statement
    right after its assignment) that says what it is."""
    import ast
    import importlib

    src = inspect.getsource(importlib.import_module(module))
    body = ast.parse(src).body
    for i, node in enumerate(body):
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == name for t in node.targets):
            nxt = body[i + 1] if i + 1 < len(body) else None
            assert isinstance(nxt, ast.Expr) and isinstance(nxt.value, ast.Constant) and len(nxt.value.value) > 20
            return
    raise AssertionError(f"{name} not assigned in {module}")

"""The docstring examples run, give what they show, and raise no warning.

The modules are those of the *installed* package (CI installs it non-editable, so the source
tree has no compiled ``_core``): every module found by :func:`pkgutil.walk_packages` is
imported and its examples are run by :mod:`doctest`, one test per module, with every warning
turned into an error. Examples run in a temporary directory, so those that write files leave
nothing behind.
"""

from __future__ import annotations

import doctest
import importlib
import inspect
import io
import pkgutil
import warnings

import pytest

import irfidelity

FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def module_names() -> list[str]:
    found = [info.name for info in pkgutil.walk_packages(irfidelity.__path__, "irfidelity.")]
    return ["irfidelity"] + sorted(n for n in found if not n.endswith("__main__"))  # __main__ runs the CLI


def examples_of(name: str) -> list[doctest.DocTest]:
    module = importlib.import_module(name)
    return [t for t in doctest.DocTestFinder(exclude_empty=True).find(module, name) if t.examples]


MODULES_WITH_EXAMPLES = [name for name in module_names() if examples_of(name)]


@pytest.mark.parametrize("name", MODULES_WITH_EXAMPLES)
def test_module_examples_pass_without_warnings(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    report = io.StringIO()
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for test in examples_of(name):
            runner.run(test, out=report.write)
    result = runner.summarize(verbose=False)
    assert result.attempted > 0
    assert result.failed == 0, report.getvalue()


def test_the_walk_finds_the_installed_modules_with_examples():
    assert {"irfidelity.evaluation", "irfidelity.registration", "irfidelity.sequence", "irfidelity.stats",
            "irfidelity.maps", "irfidelity.frames", "irfidelity.config", "irfidelity.fuzzy",
            "irfidelity.noise.model", "irfidelity.curves.edge"} <= set(MODULES_WITH_EXAMPLES)


def public_api() -> dict[str, object]:
    """The functions and classes of ``irfidelity.__all__`` and of the names moved from the top
    level to their modules (``irfidelity.stats.psnr``, ...), by their spelling, without the error
    and warning classes (whose docstrings say when they are raised, not how to call anything)."""
    found = {name: getattr(irfidelity, name) for name in irfidelity.__all__}
    for name, home in irfidelity._MOVED.items():
        found[f"{home}.{name}"] = getattr(getattr(irfidelity, home), name)
    return {
        name: obj
        for name, obj in found.items()
        if not (inspect.isclass(obj) and issubclass(obj, (Exception, Warning)))
        and (inspect.isclass(obj) or callable(obj))
    }


@pytest.mark.parametrize("name", sorted(public_api()))
def test_public_names_have_examples_that_the_module_runs(name):
    obj = public_api()[name]
    tests = doctest.DocTestFinder(exclude_empty=True).find(obj, name, module=inspect.getmodule(obj))
    assert any(t.examples for t in tests), f"irfidelity.{name} has no example in its docstring"
    assert obj.__module__ in MODULES_WITH_EXAMPLES

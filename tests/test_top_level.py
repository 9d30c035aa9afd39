"""The top level holds what a scoring session needs (issue "One scorer"); every other public
name lives in its module, and its old top-level spelling still resolves with a DeprecationWarning."""

from __future__ import annotations

import importlib
import re
import warnings

import pytest

import irfidelity

TOP_LEVEL = [
    "evaluate", "Scorer", "score_sequence", "score_simulators", "ScoringConfig", "Weights",
    "FidelityReport", "SequenceReport", "SimulatorComparison",
    "load_frame", "FrameSequence", "Curve", "Regions",
    "pair_stats", "PairStats", "register", "transfer", "read_radiometry",
    "FidelityError", "FrameError", "FidelityWarning",
]

# the modules users navigate to: attributes of the package after `import irfidelity`
SUBMODULES = ["bar_frames", "budget", "curves", "errors", "frames", "fuzzy", "maps", "noise", "radiometry",
              "registration", "schema", "sequence", "stats", "system", "targets"]


def test_the_top_level_is_the_scoring_session():
    assert sorted(irfidelity.__all__) == sorted(TOP_LEVEL)
    assert len(set(irfidelity.__all__)) == len(irfidelity.__all__) == 21


@pytest.mark.parametrize("name", TOP_LEVEL)
def test_each_top_level_name_resolves_without_warning(name):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert getattr(irfidelity, name) is not None


def test_the_version_is_there_but_not_in_all():
    assert isinstance(irfidelity.__version__, str) and "__version__" not in irfidelity.__all__


@pytest.mark.parametrize("name", SUBMODULES)
def test_the_modules_are_attributes(name):
    module = getattr(irfidelity, name)
    assert module is importlib.import_module(f"irfidelity.{name}")
    assert name not in irfidelity.__all__


@pytest.mark.parametrize("name", sorted(irfidelity._MOVED))
def test_a_moved_name_resolves_with_a_deprecation_warning(name):
    home = irfidelity._MOVED[name]
    module = importlib.import_module(f"irfidelity.{home}")
    assert name in module.__all__, f"irfidelity.{home} does not export {name}"
    message = f"irfidelity.{name} is now irfidelity.{home}.{name};"
    with pytest.warns(DeprecationWarning, match="^" + re.escape(message)) as caught:
        old = getattr(irfidelity, name)
    assert old is getattr(module, name)
    assert caught[0].filename == __file__  # the warning points at the caller's line


def test_from_import_of_a_moved_name_warns():
    with pytest.warns(DeprecationWarning, match="irfidelity.stats.psnr"):
        from irfidelity import psnr
    assert psnr is irfidelity.stats.psnr


def test_the_moved_names_left_the_top_level():
    assert not set(irfidelity._MOVED) & set(irfidelity.__all__)
    assert not set(irfidelity._MOVED) & set(vars(irfidelity))  # only __getattr__ reaches them
    assert len(irfidelity._MOVED) == 19


def test_an_unknown_name_is_an_attribute_error():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
            irfidelity.no_such_name  # noqa: B018
        assert not hasattr(irfidelity, "mse_")


def test_dir_lists_the_top_level_and_the_modules():
    listed = dir(irfidelity)
    assert not set(irfidelity._MOVED) & set(listed)
    public = {name for name in listed if not name.startswith("_")}
    assert public == set(TOP_LEVEL) | set(SUBMODULES)
    assert "__version__" in listed

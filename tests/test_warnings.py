"""Every warning irfidelity issues is a FidelityWarning, defined once in irfidelity.errors, so
the one filter the docs promise (``simplefilter("error", FidelityWarning)``) catches them all."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import warnings

import numpy as np
import pytest

import irfidelity
from irfidelity import errors
from irfidelity.errors import AHPConsistencyWarning, FidelityWarning


def package_modules() -> list:
    names = [info.name for info in pkgutil.walk_packages(irfidelity.__path__, "irfidelity.")]
    return [irfidelity] + [importlib.import_module(n) for n in names if not n.endswith("__main__")]


def warning_classes() -> dict[str, type]:
    """Every Warning subclass reachable as an attribute of a module of the package."""
    found = {}
    for module in package_modules():
        for name, obj in vars(module).items():
            if inspect.isclass(obj) and issubclass(obj, Warning) and obj.__module__.startswith("irfidelity"):
                found[f"{module.__name__}.{name}"] = obj
    return found


def test_the_walk_finds_the_warning_classes():
    names = {cls.__name__ for cls in warning_classes().values()}
    assert {"PeakWarning", "RegistrationWarning", "EdgeWarning", "CurveUnitsWarning", "NoiseWarning",
            "AHPConsistencyWarning"} <= names


@pytest.mark.parametrize("where", sorted(warning_classes()))
def test_every_warning_class_is_a_fidelity_warning_defined_in_errors(where):
    cls = warning_classes()[where]
    assert issubclass(cls, FidelityWarning), f"{where} does not derive from FidelityWarning"
    assert cls.__module__ == "irfidelity.errors", f"{where} is defined in {cls.__module__}"
    assert cls.__name__ in errors.__all__


def test_reexports_are_the_errors_classes():
    from irfidelity.curves.edge import EdgeWarning
    from irfidelity.curves.units import CurveUnitsWarning
    from irfidelity.fuzzy import AHPConsistencyWarning as FromFuzzy
    from irfidelity.noise.checks import NoiseWarning
    from irfidelity.registration import RegistrationWarning

    assert EdgeWarning is errors.EdgeWarning and CurveUnitsWarning is errors.CurveUnitsWarning
    assert FromFuzzy is errors.AHPConsistencyWarning and NoiseWarning is errors.NoiseWarning
    assert RegistrationWarning is errors.RegistrationWarning


def test_the_fidelity_filter_catches_an_inconsistent_ahp_matrix():
    # a > b, b > c, but c > a: the judgements contradict each other
    contradictory = np.array([[1, 5, 1 / 5], [1 / 5, 1, 5], [5, 1 / 5, 1]])
    with warnings.catch_warnings():
        warnings.simplefilter("error", FidelityWarning)
        with pytest.raises(AHPConsistencyWarning, match="consisten"):
            irfidelity.fuzzy.ahp(contradictory, names=["psnr", "nmi", "ssim"])

"""irfidelity: how faithfully does an infrared camera simulator reproduce the real camera?

Implements the fuzzy-logic fidelity framework of Acta Photonica Sinica 41(5):547 (2012),
doi:10.3788/gzxb20124105.0547: five components in [0, 1] (MTF and SiTF curve similarity,
normalised PSNR, NMI, global SSIM) and their weighted sum, with an exact Rust core.

The top level holds what a scoring session needs; the tools of each stage live in their
module: :mod:`irfidelity.stats` (MSE, PSNR, SSIM, NMI of a pair), :mod:`irfidelity.maps`
(SSIM maps, MS-SSIM), :mod:`irfidelity.noise` (3-D noise), :mod:`irfidelity.registration`,
:mod:`irfidelity.curves` (MTF, slanted edge, SiTF, curve similarity), :mod:`irfidelity.fuzzy`
(grades, AHP weights, comparing simulators), :mod:`irfidelity.system` (the pair's transfer:
MTF ratio, gain, noise from the scene), :mod:`irfidelity.radiometry`,
:mod:`irfidelity.targets` and :mod:`irfidelity.bar_frames` (bar targets, MRTD),
:mod:`irfidelity.frames` (channels, pages), :mod:`irfidelity.errors` (every error and warning),
:mod:`irfidelity.schema` (the names and units of every output).
"""

import warnings
from typing import TYPE_CHECKING, Any

# the stages' modules, so `irfidelity.stats` etc. work after `import irfidelity`
from . import bar_frames, budget, curves, errors, frames, fuzzy, maps, noise  # noqa: F401
from . import radiometry, registration, schema, sequence, stats, system, targets  # noqa: F401
from .config import ScoringConfig
from .curves import Curve
from .errors import FidelityError, FidelityWarning, FrameError
from .evaluation import Scorer, evaluate
from .frames import FrameSequence, load_frame
from .fuzzy import Weights
from .results import FidelityReport
from .radiometry import read_radiometry
from .registration import register
from .regions import Regions
from .sequence import SequenceReport, score_sequence
from .simulators import SimulatorComparison, score_simulators
from .stats import PairStats, pair_stats
from .system import transfer
from ._version import __version__  # noqa: F401

__all__ = [
    # scoring
    "evaluate",
    "Scorer",
    "score_sequence",
    "score_simulators",
    "ScoringConfig",
    "Weights",
    # reports
    "FidelityReport",
    "SequenceReport",
    "SimulatorComparison",
    # inputs
    "load_frame",
    "FrameSequence",
    "Curve",
    "Regions",
    # what a scoring session computes on its own: a pair's statistics, its registration and
    # transfer, temperatures
    "pair_stats",
    "PairStats",
    "register",
    "transfer",
    "read_radiometry",
    # the errors and the warning a caller catches or filters (the rest: irfidelity.errors)
    "FidelityError",
    "FrameError",
    "FidelityWarning",
]

# The modules a user navigates to, listed by dir() beside __all__.
_SUBMODULES = ("bar_frames", "budget", "curves", "errors", "frames", "fuzzy", "maps", "noise", "radiometry",
               "registration", "schema", "sequence", "stats", "system", "targets")

# Names the top level held before it kept only what a scoring session needs: each one's module.
# Still reachable as `irfidelity.<name>`, with a DeprecationWarning naming the new spelling.
_MOVED = {
    "mse": "stats",
    "psnr": "stats",
    "ssim": "stats",
    "nmi": "stats",
    "ssim_map": "maps",
    "SSIMMap": "maps",
    "ms_ssim": "maps",
    "noise3d": "noise",
    "Noise3D": "noise",
    "noise_similarity": "noise",
    "NoiseWarning": "noise",
    "Registration": "registration",
    "RegistrationWarning": "registration",
    "Transfer": "system",
    "Radiometry": "radiometry",
    "BarFrames": "bar_frames",
    "ShapeError": "errors",
    "RangeError": "errors",
    "RegistrationError": "errors",
}


# Hidden from type checkers: a module __getattr__ would make them accept any misspelt
# `irfidelity.<name>`; to them the moved names are gone, to running scripts they only warn.
if not TYPE_CHECKING:

    def __getattr__(name: str) -> Any:
        """A moved name from its module, with a DeprecationWarning; any other unknown name fails."""
        home = _MOVED.get(name)
        if home is None:
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
        warnings.warn(f"irfidelity.{name} is now irfidelity.{home}.{name}; the top level keeps what a scoring "
                      f"session needs", DeprecationWarning, stacklevel=2)
        return getattr(globals()[home], name)  # every home module is imported above


def __dir__() -> list[str]:
    """The top level and the stages' modules (what tab completion and help() show)."""
    return sorted([*__all__, "__version__", *_SUBMODULES])

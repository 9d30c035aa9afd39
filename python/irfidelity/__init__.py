"""irfidelity: how faithfully does an infrared camera simulator reproduce the real camera?

Implements the fuzzy-logic fidelity framework of Acta Photonica Sinica 41(5):547 (2012),
doi:10.3788/gzxb20124105.0547: five components in [0, 1] (MTF and SiTF curve similarity,
normalised PSNR, NMI, global SSIM) and their weighted sum, with an exact Rust core.

The top level holds what a scoring session needs; the tools of each stage live in their
module: :mod:`irfidelity.curves` (MTF, slanted edge, SiTF, curve similarity),
:mod:`irfidelity.fuzzy` (grades, AHP weights, comparing simulators), :mod:`irfidelity.system`
(the pair's transfer: MTF ratio, gain, noise from the scene), :mod:`irfidelity.frames`
(channels, pages), :mod:`irfidelity.schema` (the names and units of every output).
"""

# the stages' modules, so `irfidelity.curves` etc. work after `import irfidelity`
from . import curves, fuzzy  # noqa: F401
from . import targets  # noqa: F401
from .bar_frames import BarFrames
from .config import ScoringConfig
from .curves import Curve
from .errors import FidelityError, FidelityWarning, FrameError, RangeError, RegistrationError, ShapeError
from .evaluation import evaluate
from .frames import FrameSequence, load_frame
from .fuzzy import Weights
from .maps import SSIMMap, ms_ssim, ssim_map
from .noise import Noise3D, NoiseWarning, noise3d, noise_similarity
from .results import FidelityReport
from .radiometry import Radiometry, read_radiometry
from .registration import Registration, RegistrationWarning, register
from .regions import Regions
from .sequence import SequenceReport, score_sequence
from .simulators import SimulatorComparison, score_simulators
from .stats import PairStats, mse, nmi, pair_stats, psnr, ssim
from .system import Transfer, transfer
from ._version import __version__  # noqa: F401

__all__ = [
    # scoring
    "evaluate",
    "score_sequence",
    "FidelityReport",
    "SequenceReport",
    "score_simulators",
    "SimulatorComparison",
    "ScoringConfig",
    "Weights",
    # frame statistics and image metrics
    "pair_stats",
    "PairStats",
    "mse",
    "psnr",
    "ssim",
    "nmi",
    # inputs
    "load_frame",
    "FrameSequence",
    "Curve",
    "BarFrames",
    "Regions",
    # physical units (docs/radiometry.md)
    "read_radiometry",
    "Radiometry",
    # where frames differ
    "ssim_map",
    "SSIMMap",
    "ms_ssim",
    # sensor noise (3-D noise, the opt-in component `noise`)
    "noise3d",
    "Noise3D",
    "noise_similarity",
    "NoiseWarning",
    # the pair as a system: the simulator's MTF, gain and noise relative to the camera's
    "transfer",
    "Transfer",
    # registration (docs/registration.md)
    "register",
    "Registration",
    "RegistrationWarning",
    # errors and warnings
    "FidelityError",
    "FrameError",
    "ShapeError",
    "RangeError",
    "RegistrationError",
    "FidelityWarning",
]

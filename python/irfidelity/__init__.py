"""irfidelity: how faithfully does an infrared camera simulator reproduce the real camera?

Implements the fuzzy-logic fidelity framework of Acta Photonica Sinica 41(5):547 (2012),
doi:10.3788/gzxb20124105.0547: five components in [0, 1] (MTF and SiTF curve similarity,
normalised PSNR, NMI, global SSIM) and their weighted sum, with an exact Rust core.
"""

from .curves import Curve, CurveSimilarity, curve_similarity, cy_per_mrad_to_cy_per_px, cy_per_px_to_cy_per_mrad
from .edge import EdgeWarning, mtf_from_edge
from .errors import FidelityError, FrameError, RangeError, ShapeError
from .evaluation import FidelityReport, evaluate, image_components, plan_components
from .frames import FrameSequence, list_channels, load_frame, page_count
from .fuzzy import AHPConsistencyWarning, Comparison, GradeScale, Weights, ahp, compare
from .metrics import NMI, SSIM
from .mtf import mtf50, mtf_from_esf, mtf_from_lsf, mtf_similarity
from .normalize import normalize_psnr
from .registration import Registration, RegistrationWarning, register
from .sequence import SequenceReport, score_sequence
from .sitf import SiTFFit, netd, sitf_fit, sitf_similarity
from .stats import PairStats, mse, nmi, pair_stats, psnr, ssim

__version__ = "0.1.0"

__all__ = [
    "FidelityError",
    "FrameError",
    "RangeError",
    "ShapeError",
    "NMI",
    "SSIM",
    "PairStats",
    "pair_stats",
    "mse",
    "psnr",
    "ssim",
    "nmi",
    "normalize_psnr",
    "Curve",
    "CurveSimilarity",
    "curve_similarity",
    "cy_per_mrad_to_cy_per_px",
    "cy_per_px_to_cy_per_mrad",
    "mtf50",
    "mtf_from_esf",
    "mtf_from_lsf",
    "mtf_similarity",
    "EdgeWarning",
    "mtf_from_edge",
    "SiTFFit",
    "netd",
    "sitf_fit",
    "sitf_similarity",
    "FidelityReport",
    "evaluate",
    "plan_components",
    "image_components",
    "Weights",
    "GradeScale",
    "ahp",
    "AHPConsistencyWarning",
    "compare",
    "Comparison",
    "FrameSequence",
    "load_frame",
    "list_channels",
    "page_count",
    "score_sequence",
    "SequenceReport",
    # registration (docs/registration.md)
    "register",
    "Registration",
    "RegistrationWarning",
]

"""Camera curves: the MTF and SiTF components f1, f2 of the fidelity (paper §1, eqs. 1-4).

* :class:`Curve` — a sampled curve with the units of both axes, read from CSV with
  :meth:`Curve.from_csv` (units from the header names; the table is in :mod:`.units`);
* MTF: :func:`mtf_from_lsf`, :func:`mtf_from_esf`, :func:`mtf_from_edge` (ISO 12233:2023
  slanted edge), :func:`mtf50`, component f1 :func:`mtf_similarity`;
* SiTF: :func:`sitf_fit`, :func:`netd`, component f2 :func:`sitf_similarity`;
* bar targets: :func:`ctf_from_bars` (bar modulation and fundamental-amplitude ratio, a
  :class:`BarReading`), :func:`ctf_curve`, :func:`find_bars`; Coltman's series
  :func:`ctf_from_mtf`, :func:`mtf_from_ctf`; MRTD :func:`mrtd` (model) and
  :func:`measured_mrtd`, the ``mrtd`` component :func:`mrtd_similarity` (docs/bars.md);
* :func:`curve_similarity` (eqs. 1-4) and its result :class:`CurveSimilarity`;
* :class:`CameraGeometry` — IFOV, pixel pitch, focal length for frequency conversions.

Everything is numpy. References: Acta Photonica Sinica 41(5):547 (2012),
doi:10.3788/gzxb20124105.0547; ISO 12233:2023; Coltman, JOSA 44(6):468 (1954).
"""

from .bars import BarGroup, find_bars
from .ctf import BarReading, ctf_curve, ctf_from_bars, ctf_from_mtf, mtf_from_ctf
from .curve import Curve
from .edge import EdgeWarning, mtf_from_edge
from .mtf import mtf50, mtf_from_esf, mtf_from_lsf, mtf_similarity
from .mrtd import measured_mrtd, mrtd
from .mrtd_similarity import MRTDSimilarity, mrtd_similarity
from .similarity import CurveSimilarity, curve_similarity
from .sitf import SiTFFit, netd, sitf_fit, sitf_similarity
from .units import CameraGeometry, CurveUnitsWarning

__all__ = [
    "Curve",
    "CameraGeometry",
    "CurveSimilarity",
    "curve_similarity",
    "mtf_from_lsf",
    "mtf_from_esf",
    "mtf_from_edge",
    "mtf50",
    "mtf_similarity",
    "SiTFFit",
    "sitf_fit",
    "netd",
    "sitf_similarity",
    "ctf_from_bars",
    "BarReading",
    "ctf_curve",
    "find_bars",
    "BarGroup",
    "ctf_from_mtf",
    "mtf_from_ctf",
    "mrtd",
    "measured_mrtd",
    "mrtd_similarity",
    "MRTDSimilarity",
    "EdgeWarning",
    "CurveUnitsWarning",
]

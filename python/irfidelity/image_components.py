"""The image components f3..f5 of a pair from its statistics (paper §2, eqs. 5–14): what
scoring a pair (:mod:`irfidelity.scoring`) and measuring its ceiling (:mod:`irfidelity.ceiling`)
both compute.
"""

from __future__ import annotations

from typing import Any

from .config import ScoringConfig
from .normalize import normalize_psnr

__all__ = ["image_components"]


def image_components(stats: Any, components: tuple[str, ...], config: ScoringConfig) -> tuple[dict, dict]:
    """Components f3 (normalised PSNR), f4 (NMI), f5 (max(SSIM, 0)) from a PairStats.

    Only ``components`` are computed (and only their raw metrics reported), so ``stats``
    need only hold what the plan asked for.

    Returns
    -------
    (components, metrics)
        ``{"psnr"|"nmi"|"ssim": f}`` and the raw values (:data:`irfidelity.schema.METRICS`)
        with ``n``, ``masked`` and ``nonfinite``.
    """
    comps: dict[str, float] = {}
    mets: dict[str, Any] = {"n": int(stats.n), "masked": int(stats.masked), "nonfinite": int(stats.nonfinite)}
    if "psnr" in components:
        db = float(stats.psnr())
        mets.update(mse=float(stats.mse()), psnr_db=db, psnr_peak=float(stats.peak))
        comps["psnr"] = float(normalize_psnr(db, anchors=config.psnr_anchors))
    if "nmi" in components:
        v = stats.nmi()
        mets.update(nmi=float(v.value), mi=float(v.mi), h_real=float(v.h_real), h_sim=float(v.h_sim),
                    h_joint=float(v.h_joint))
        comps["nmi"] = float(v.value)
    if "ssim" in components:
        # the configuration checked the exponents
        value, luminance, contrast, structure = map(float, stats.ssim_terms(*config.ssim_exponents))
        mets.update(ssim=value, ssim_luminance=luminance, ssim_contrast=contrast, ssim_structure=structure)
        comps["ssim"] = max(value, 0.0)
    return comps, mets

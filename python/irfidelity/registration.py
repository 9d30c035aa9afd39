"""Registration of a simulated frame onto the real one (paper §2.4).

"If the position of the target in the actual image does not perfectly accord with that in
the simulated one, image registration is required before the quality metrics." A simulated
target is never on exactly the real one's pixels, and PSNR, NMI and SSIM would measure the
misalignment rather than the simulator. :func:`register` finds the transform (in Rust, with
the GIL released) and :meth:`Registration.apply` resamples the simulated frame onto the real
one with the mask of the pixels it covers.

Conventions (the same as OpenCV and scikit-image):

- ``reg.matrix`` (2×3) maps simulated pixel coordinates ``(x, y) = (column, row)`` to real
  ones: ``real(M·p) ≈ sim(p)``, i.e. ``cv2.warpAffine(sim, reg.matrix, (w, h)) ≈ real``;
- ``reg.shift = (dy, dx)`` follows ``skimage.registration.phase_cross_correlation(real,
  sim)``: ``real ≈ scipy.ndimage.shift(sim, reg.shift)``;
- ``reg.angle`` in degrees follows ``cv2.getRotationMatrix2D``: positive turns the image
  counter-clockwise as displayed (y axis down).

See docs/registration.md for the methods, the confidence, and how interpolation changes what
the metrics measure.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from . import _core
from .budget import resolve
from .config_fields import REGISTRATION_METHODS, REGISTRATION_MODELS
from .errors import FidelityError, RegistrationWarning, ShapeError
from .stats import _as_frame

__all__ = ["register", "Registration", "RegistrationWarning", "MODELS", "METHODS", "DEFAULT_METHOD",
           "LOW_CONFIDENCE", "DEFAULT_ORDER", "INTEGER_SNAP"]

MODELS = REGISTRATION_MODELS
METHODS = REGISTRATION_METHODS
#: The method used unless one is given (:func:`register`, ``ScoringConfig.register_method``,
#: ``--register-method``). Phase correlation: on simulations of real frames it is within
#: 0.08 px of the true transform in a fraction of ``"auto"``'s time, and ``"auto"``'s
#: refinement of translations moves PSNR by at most 0.15 dB (benches/bench_register.py,
#: docs/registration.md "Which method by default"). Rotation and scale are refined either way.
DEFAULT_METHOD = "phase"
#: Below this confidence a registration warns (:class:`RegistrationWarning`); below
#: ``_core.REGISTRATION_AMBIGUOUS`` it is refused.
LOW_CONFIDENCE: float = _core.REGISTRATION_LOW_CONFIDENCE
#: Interpolation order of :meth:`Registration.apply`: 3 (Keys bicubic). Resampling smooths
#: the simulated noise and so raises PSNR/NMI/SSIM; bicubic keeps 64–96 % of the noise's std
#: where bilinear keeps 50–82 %, and biases PSNR least (≤ 0.05 dB up to 0.05 px, ≤ 1.5 dB
#: at half a pixel; benches/bench_interpolation.py, docs/registration.md).
DEFAULT_ORDER = 3
#: A translation within this many pixels of whole pixels is applied as the whole-pixel
#: shift (values copied). Measured, snapping a subpixel part f misaligns by f and biases
#: PSNR more than bicubic resampling does for f ≥ 0.02 px on a clean frame, so only
#: shifts whole to within the registration's own precision are snapped (docs/registration.md).
INTEGER_SNAP: float = _core.REGISTRATION_INTEGER_SNAP


def _matrix_tuple(m: Any) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    arr = np.asarray(m, dtype=np.float64)
    if arr.shape != (2, 3) or not np.all(np.isfinite(arr)):
        raise FidelityError(f"matrix must be a finite 2×3 array, got {np.asarray(m).shape}")
    return (tuple(float(v) + 0.0 for v in arr[0]), tuple(float(v) + 0.0 for v in arr[1]))  # type: ignore[return-value]


@dataclass(frozen=True)
class Registration:
    """A transform taking the simulated frame onto the real one, and how far to trust it.

    Attributes
    ----------
    matrix : ndarray, shape (2, 3)
        Simulated → real pixel coordinates (x = column, y = row, pixel centres at integers):
        ``real(M·p) ≈ sim(p)``, so ``cv2.warpAffine(sim, matrix, (w, h)) ≈ real``.
    shift : (float, float)
        ``(dy, dx)``: the displacement of the frame centre. For ``model="translation"`` this
        is the whole transform and ``real ≈ scipy.ndimage.shift(sim, shift)`` (the sign of
        ``skimage.registration.phase_cross_correlation(real, sim)``).
    angle : float
        Rotation in degrees, ``cv2.getRotationMatrix2D`` sense (counter-clockwise as
        displayed); 0 for translation.
    scale : float
        Uniform scale (1 for translation and rigid).
    model : {"translation", "rigid", "similarity"}
    method : {"phase", "nmi"}
        The method whose result was kept (``"auto"`` reports the one it kept).
    confidence : float
        Distinctness of the match in [0, 1]: ``1 − (best rival)/(best)`` — 1 when no other
        shift matches, near 0 when another does (periodic patterns, unrelated or
        featureless frames). Below :data:`LOW_CONFIDENCE` :func:`register` warns.
    overlap : float
        Fraction of the real frame covered by the warped simulated frame.
    shape : (int, int)
        ``(rows, cols)`` of the frames registered.
    inverted : bool
        The registered frames correlate negatively (inverted grey levels).
    """

    _matrix: tuple
    model: str
    method: str
    confidence: float
    overlap: float
    shape: tuple
    inverted: bool = False

    # -- the transform ---------------------------------------------------------------
    @property
    def matrix(self) -> np.ndarray:
        return np.array(self._matrix, dtype=np.float64)

    @property
    def shift(self) -> tuple[float, float]:
        m = self.matrix
        rows, cols = self.shape
        cx, cy = (cols - 1) / 2.0, (rows - 1) / 2.0
        x, y = m @ np.array([cx, cy, 1.0])
        return (float(y - cy), float(x - cx))

    @property
    def angle(self) -> float:
        m = self.matrix
        return math.degrees(math.atan2(m[0, 1] - m[1, 0], m[0, 0] + m[1, 1]))

    @property
    def scale(self) -> float:
        m = self.matrix
        return math.sqrt(abs(m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]))

    # -- applying it ----------------------------------------------------------------
    def apply(self, sim: Any, *, order: int = DEFAULT_ORDER, mask: Any = None,
              max_bytes: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Resample the simulated frame onto the real frame's pixels.

        ``out(q) = sim(M⁻¹·q)`` with bilinear (``order=1``) or Keys bicubic (``order=3``,
        a = −0.5) interpolation, computed in Rust. A pixel is valid when every simulated
        pixel with a non-zero interpolation weight lies inside the frame, is finite and is
        not masked; invalid pixels are NaN. A translation within :data:`INTEGER_SNAP` px of
        whole pixels is applied as the whole-pixel shift (values copied, no smoothing).

        Parameters
        ----------
        sim : 2-D array or frame path
            The simulated frame (any supported dtype), of shape ``self.shape``.
        order : {1, 3}
            Interpolation order.
        mask : bool array, optional
            False marks simulated pixels that must not be used.
        max_bytes : int, optional
            The memory budget (default :data:`irfidelity.budget.DEFAULT_MAX_BYTES`): the frame,
            its mask and the output (9 bytes a pixel) must fit, else a :class:`FidelityError`
            before anything is allocated (docs/design.md §14).

        Returns
        -------
        (aligned, valid) : (float64 ndarray, bool ndarray)
            Both of shape ``self.shape``.

        Examples
        --------
        >>> import numpy as np, irfidelity as irf
        >>> reg = irf.registration.Registration.from_dict({"model": "translation", "method": "phase",
        ...     "matrix": [[1, 0, 2], [0, 1, -1]], "confidence": 1.0, "overlap": 0.9,
        ...     "shape": [4, 5]})
        >>> out, valid = reg.apply(np.arange(20, dtype=np.uint16).reshape(4, 5))
        >>> float(out[1, 2]), bool(valid[0, 0])       # sim[2, 0] moved by (dy, dx) = (-1, 2)
        (10.0, False)
        """
        frame = np.ascontiguousarray(_as_frame(sim, "sim"))
        if frame.shape != tuple(self.shape):
            raise ShapeError(f"sim has shape {frame.shape}, the registration was made for {tuple(self.shape)}")
        if order not in (1, 3):
            raise FidelityError(f"order must be 1 (bilinear) or 3 (bicubic), got {order!r}")
        if mask is not None:
            mask = np.ascontiguousarray(mask, dtype=bool)
            if mask.shape != frame.shape:
                raise ShapeError(f"mask has shape {mask.shape}, sim has {frame.shape}")
        m = self.applied_matrix()
        return _core.warp_frame(frame, tuple(m.ravel()), int(order), tuple(self.shape), mask, max_bytes=resolve(max_bytes))

    def applied_matrix(self) -> np.ndarray:
        """The matrix :meth:`apply` uses: integer-snapped for near-whole-pixel translations."""
        return np.asarray(_core.applied_matrix(tuple(float(v) for v in self.matrix.ravel()))).reshape(2, 3)

    # -- serialisation --------------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-ready dict: model, method, matrix, shift, angle, scale, confidence, overlap,
        shape, inverted. :meth:`from_dict` reads it back."""
        return {
            "model": self.model,
            "method": self.method,
            "matrix": [list(row) for row in self._matrix],
            "shift": list(self.shift),
            "angle": self.angle,
            "scale": self.scale,
            "confidence": self.confidence,
            "overlap": self.overlap,
            "shape": list(self.shape),
            "inverted": self.inverted,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Registration:
        try:
            model, method = str(d["model"]), str(d["method"])
            if model not in MODELS:
                raise FidelityError(f"not a Registration dict: model {model!r} is not one of {MODELS}")
            if method not in ("phase", "nmi"):
                raise FidelityError(f"not a Registration dict: method {method!r} is not 'phase' or 'nmi'")
            rows, cols = (int(v) for v in d["shape"])
            return cls(_matrix=_matrix_tuple(d["matrix"]), model=model, method=method,
                       confidence=float(d["confidence"]), overlap=float(d["overlap"]), shape=(rows, cols),
                       inverted=bool(d.get("inverted", False)))
        except KeyError as exc:
            raise FidelityError(f"not a Registration dict: missing key {exc}") from None

    def __repr__(self) -> str:
        dy, dx = self.shift
        parts = [f"model={self.model!r}", f"method={self.method!r}", f"shift=({dy:.3f}, {dx:.3f})"]
        if self.model != "translation":
            parts.append(f"angle={self.angle:.4f}")
        if self.model == "similarity":
            parts.append(f"scale={self.scale:.5f}")
        parts += [f"confidence={self.confidence:.3f}", f"overlap={self.overlap:.3f}"]
        if self.inverted:
            parts.append("inverted=True")
        return f"Registration({', '.join(parts)})"


def from_engine(found: tuple, model: str, shape: tuple) -> Registration:
    """A :class:`Registration` from the engine's ``(matrix, method, confidence, overlap,
    inverted)`` (``_core.register_frames``, or a sequence pair's own registration)."""
    matrix, used, confidence, overlap, inverted = found
    return Registration(_matrix=_matrix_tuple(np.reshape(matrix, (2, 3))), model=model, method=used,
                        confidence=float(confidence), overlap=float(overlap),
                        shape=(int(shape[0]), int(shape[1])), inverted=bool(inverted))


def _check_choice(value: Any, name: str, choices: tuple) -> str:
    if not isinstance(value, str) or value not in choices:
        raise FidelityError(f"{name} must be one of {', '.join(repr(c) for c in choices)}, got {value!r}")
    return value


def register(real: Any, sim: Any, *, model: str = "translation", method: str = DEFAULT_METHOD,
             max_shift: float | None = None, mask: Any = None, max_bytes: int | None = None) -> Registration:
    """Find the transform that takes the simulated frame onto the real one.

    The transform ``M`` (simulated → real pixel coordinates) of the model that best
    explains ``real(M·p) ≈ g·sim(p) + o`` over the pixels both frames cover, for some
    grey-level gain ``g`` (possibly negative) and offset ``o``:

    - ``method="phase"``: Fourier phase correlation of the Tukey-windowed frames (half
      whitened, subpixel peak by Newton's method on the band-limited correlation — the
      maximum that DFT upsampling samples, Guizar-Sicairos et al. 2008); for rotation and
      scale first the log-polar magnitude spectra (Reddy & Chatterji 1996), then a
      Gauss–Newton refinement on the pixel values with the gain and offset (a translation is
      final without it).
    - ``method="nmi"``: maximise the normalised mutual information ``2·MI/(H(R)+H(S))`` of
      the joint histogram (Pluim et al. 2003), for grey levels related non-linearly or
      inversely: an exhaustive coarse shift search, then Nelder–Mead.
    - ``method="auto"``: phase, a translation refined too; NMI as well when phase
      correlation is unsure (confidence below :data:`LOW_CONFIDENCE`), keeping the more
      distinct match.

    Parameters
    ----------
    real, sim : 2-D arrays or frame paths
        Same shape; any supported dtype each (uint8, uint16, int16, uint32, float16,
        float32, float64), converted to float64 once. NaN/Inf pixels are excluded.
    model : {"translation", "rigid", "similarity"}
        Shift; shift and rotation; shift, rotation and uniform scale.
    method : {"auto", "phase", "nmi"}
        Default :data:`DEFAULT_METHOD` (``"phase"``).
    max_shift : float, optional
        No frame corner may move more than this many pixels along x or y. The search is
        confined to it; a best match beyond it raises. Default: up to half the frame.
    mask : bool array, optional
        False excludes a pixel position in both frames (dead pixels, burned-in overlays).
    max_bytes : int, optional
        The memory budget (default :data:`irfidelity.budget.DEFAULT_MAX_BYTES`): the frames
        and the search's working memory must fit, else a :class:`RegistrationError` before
        anything is allocated (docs/design.md §14 has the estimates).

    Returns
    -------
    Registration

    Raises
    ------
    RegistrationError
        A flat frame, too few valid pixels, no overlap, a match beyond ``max_shift``, or an
        ambiguous match (confidence below 0.1: periodic patterns such as bar targets,
        unrelated or featureless frames). The message says which. Never an identity
        transform in place of an answer. Also frames too large for ``max_bytes``.
    ShapeError
        Frames of different shapes, not 2-D, or of an unsupported dtype.

    Warns
    -----
    RegistrationWarning
        The confidence is below :data:`LOW_CONFIDENCE`.

    Examples
    --------
    >>> import numpy as np, scipy.ndimage as ndi, irfidelity as irf
    >>> from irfidelity.demo import load_demo_data
    >>> real = ndi.gaussian_filter(load_demo_data()["frame"].astype(float), 0.7)
    >>> sim = ndi.shift(real, (-2.3, 1.6), order=3, mode="nearest")   # the simulated view
    >>> reg = irf.register(real, sim)
    >>> [round(v, 1) for v in reg.shift]                                # real ≈ shift(sim, reg.shift)
    [2.3, -1.6]
    >>> reg = irf.register(real, sim, method="auto")                    # refined: within 0.01 px
    >>> [round(v, 2) for v in reg.shift]
    [2.3, -1.6]
    >>> aligned, valid = reg.apply(sim)                                 # sim on real's pixels

    References
    ----------
    .. [1] M. Guizar-Sicairos, S. T. Thurman, J. R. Fienup, "Efficient subpixel image
       registration algorithms", Opt. Lett. 33(2):156 (2008).
    .. [2] B. S. Reddy, B. N. Chatterji, "An FFT-based technique for translation, rotation,
       and scale-invariant image registration", IEEE Trans. Image Process. 5(8):1266 (1996).
    .. [3] J. P. W. Pluim, J. B. A. Maintz, M. A. Viergever, "Mutual-information-based
       registration of medical images: a survey", IEEE Trans. Med. Imaging 22(8):986 (2003).
    .. [4] G. D. Evangelidis, E. Z. Psarakis, "Parametric image alignment using enhanced
       correlation coefficient maximization", IEEE TPAMI 30(10):1858 (2008).
    """
    _check_choice(model, "model", MODELS)
    _check_choice(method, "method", METHODS)
    if max_shift is not None:
        try:
            max_shift = float(max_shift)
        except (TypeError, ValueError):
            raise FidelityError(f"max_shift must be a number of pixels or None, got {max_shift!r}") from None
    r = np.ascontiguousarray(_as_frame(real, "real"))
    s = np.ascontiguousarray(_as_frame(sim, "sim"))
    if mask is not None:
        mask = np.ascontiguousarray(mask, dtype=bool)
        if mask.shape != r.shape:
            raise ShapeError(f"mask has shape {mask.shape}, frames have {r.shape}")
    found = _core.register_frames(r, s, model, method, max_shift, mask, max_bytes=resolve(max_bytes))
    reg = from_engine(found, model, r.shape)
    warn_if_unsure(reg, stacklevel=3)
    return reg


def warn_if_unsure(reg: Registration, stacklevel: int = 4) -> None:
    """A :class:`RegistrationWarning` when ``reg``'s confidence is below :data:`LOW_CONFIDENCE`."""
    if reg.confidence < LOW_CONFIDENCE:
        warnings.warn(RegistrationWarning(
            f"unsure registration: confidence {reg.confidence:.3f} < {LOW_CONFIDENCE} (another transform matches "
            f"nearly as well); check the pair or restrict max_shift. {reg!r}"), stacklevel=stacklevel)

"""Labelled regions of a scene (a target and its background, ...), each scored on its own.

A :class:`Regions` is a label image — 0 not scored, 1..255 one region each — with a name per
label. ``evaluate(real, sim, regions=...)`` scores the whole (the pixels of every region, within
``mask=``) exactly as ``evaluate(mask=...)`` of that union would, and then each region with the
same statistics (:func:`irfidelity.pair_stats` over the region's mask, one Rust call, GIL
released) and the same scoring (:func:`irfidelity.scoring.score_components`): a region's
entry in ``report.regions`` equals ``evaluate(mask=that region)``. The camera components (mtf,
sitf, noise, mrtd) describe the camera, not a part of the scene: a region reuses the pair's
values, so its fidelity and grade differ from the pair's only through its image components
(psnr, nmi, ssim, radiometry). A registered pair is registered once, on the union; each
region is then scored on the real frame's grid within the overlap.

Memory (docs/design.md §14): the label image is one byte a pixel, and one region's mask (one
byte a pixel) exists at a time.
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from . import budget
from . import stats as _stats
from .config import ScoringConfig
from .errors import FidelityError, PeakWarning, RangeError, ShapeError
from .fuzzy import Weights
from .scoring import image_components, psnr_peak, score_components
from .temperature import TemperatureErrors, temperature_scores, tolerance_for

__all__ = ["Regions", "as_regions", "masked_stats", "with_psnr_peak", "score_regions", "registered_union", "scored_frames",
           "region_columns", "region_values", "MAX_LABEL"]

#: The largest label: a label image is one byte a pixel.
MAX_LABEL = 255

#: A region's name: it becomes part of CSV column names (``region_<name>_f_ssim``).
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")

#: The image components (and the temperature errors) a region has of its own.
OWN_COMPONENTS = ("psnr", "nmi", "ssim", "radiometry")


def _fail(message: str, kind: type = FidelityError) -> FidelityError:
    return kind(f"regions: {message}", option="regions")


def _label_image(labels: Any) -> np.ndarray:
    """``labels`` as a 2-D uint8 array (bool: label 1), checked: integers in 0..255."""
    values = np.asarray(labels)
    if values.ndim != 2:
        raise _fail(f"expected a 2-D label image, got shape {values.shape}", ShapeError)
    if values.dtype == np.bool_:
        return values.view(np.uint8)
    if values.dtype.kind not in "ui":
        raise _fail(f"expected integer labels (0 not scored, 1..{MAX_LABEL} a region), got dtype {values.dtype}: "
                    "round or cast the label image to an integer type", ShapeError)
    if values.size and (values.min() < 0 or values.max() > MAX_LABEL):
        bad = (values < 0) | (values > MAX_LABEL)
        row, col = np.argwhere(bad)[0]
        raise _fail(f"label {values[row, col]} at row {row}, column {col} is outside 0..{MAX_LABEL} "
                    f"({int(bad.sum())} pixels are)", RangeError)
    return values if values.dtype == np.uint8 else values.astype(np.uint8)


def _named(names: Any, present: list[int]) -> dict[int, str]:
    """``{label: name}`` from ``names`` (None: each label its number; a sequence: labels 1, 2,
    ...; a mapping name → label, or label → name), checked."""
    if names is None:
        return {k: str(k) for k in present}
    if isinstance(names, str):
        raise _fail(f"names must be a list of names or a mapping name → label, got the string {names!r}")
    if isinstance(names, Mapping):
        pairs = [(key, value) if isinstance(value, str) else (value, key) for key, value in names.items()]
    elif isinstance(names, Sequence):
        pairs = list(enumerate(names, start=1))
    else:
        raise _fail(f"names must be a list of names or a mapping name → label, got {type(names).__name__}")
    out: dict[int, str] = {}
    for label, name in pairs:
        if isinstance(label, bool) or not isinstance(label, (int, np.integer)) or not 1 <= label <= MAX_LABEL:
            raise _fail(f"the label of {name!r} must be an integer in 1..{MAX_LABEL}, got {label!r}")
        if not isinstance(name, str) or not _NAME.match(name):
            raise _fail(f"a region's name is letters, digits, '_', '.', '-' (starting with a letter or digit), "
                        f"got {name!r}")
        if int(label) in out:
            raise _fail(f"label {label} is named twice ({out[int(label)]!r} and {name!r})")
        out[int(label)] = name
    if len(set(out.values())) != len(out):
        raise _fail(f"names must differ, got {list(out.values())}")
    return dict(sorted(out.items()))


class Regions:
    """Labelled regions of a frame: a label image and a name per label.

    Parameters
    ----------
    labels : 2-D integer (or bool) array
        0: the pixel is not scored; 1..255: the region it belongs to. Stored as uint8 (one byte
        a pixel; uint8 input is kept without a copy). Float labels are an error.
    names : sequence of str or mapping, optional
        A list names labels 1, 2, ... in order; a mapping ``{name: label}`` (or
        ``{label: name}``) names any labels.
        Names are letters, digits, ``_``, ``.``, ``-`` (they become CSV column names). Default:
        each label present its number (``"1"``, ``"2"``). Every named label must have a pixel,
        and with names every label present must be named.

    Attributes
    ----------
    labels : ndarray of uint8
    names : dict
        ``{label: name}``, labels ascending (the order of reports and CSV columns).
    pixels : dict
        ``{name: pixels carrying the label}``.

    Examples
    --------
    >>> import numpy as np, irfidelity as irf
    >>> labels = np.zeros((4, 6), dtype=np.uint8)
    >>> labels[1:3, 1:3] = 1                                # the target
    >>> labels[:, 4:] = 2                                   # the background
    >>> regions = irf.Regions(labels, names=["target", "background"])
    >>> regions.names, regions.pixels
    ({1: 'target', 2: 'background'}, {'target': 4, 'background': 8})
    >>> irf.Regions.from_masks({"hot": labels == 1}).names
    {1: 'hot'}
    """

    __slots__ = ("labels", "names", "pixels")

    def __init__(self, labels: Any, names: Any = None):
        values = _label_image(labels)
        counts = np.bincount(values.ravel(), minlength=MAX_LABEL + 1)
        present = [k for k in range(1, MAX_LABEL + 1) if counts[k]]
        named = _named(names, present)
        if not named:
            raise _fail(f"no pixel carries a label (1..{MAX_LABEL}; 0 is not scored): nothing to score")
        for label, name in named.items():
            if not counts[label]:
                raise _fail(f"region {name!r} (label {label}) has no pixels in the label image")
        unnamed = [k for k in present if k not in named]
        if unnamed:
            raise _fail(f"label {unnamed[0]} ({int(counts[unnamed[0]])} pixels) has no name: name every label "
                        f"present ({', '.join(map(str, present))}) or none")
        self.labels, self.names = values, named
        self.pixels = {name: int(counts[label]) for label, name in named.items()}

    @classmethod
    def from_masks(cls, masks: Mapping[str, Any]) -> Regions:
        """Regions from ``{name: 2-D bool array}`` (labels 1, 2, ... in the mapping's order);
        the masks must not overlap and each must hold a pixel."""
        if not isinstance(masks, Mapping) or not masks:
            raise _fail("expected a non-empty mapping {name: 2-D bool array}")
        if len(masks) > MAX_LABEL:
            raise _fail(f"at most {MAX_LABEL} regions, got {len(masks)}")
        labels: np.ndarray | None = None
        for label, (name, mask) in enumerate(masks.items(), start=1):
            m = np.asarray(mask)
            if m.dtype != np.bool_ or m.ndim != 2:
                raise _fail(f"region {name!r}: expected a 2-D bool array, got {m.dtype} of shape {m.shape}", ShapeError)
            if labels is None:
                labels = np.zeros(m.shape, dtype=np.uint8)
            elif m.shape != labels.shape:
                raise _fail(f"region {name!r} has shape {m.shape}, the first region {labels.shape}", ShapeError)
            if not m.any():
                raise _fail(f"region {name!r} has no pixels")
            taken = m & (labels != 0)
            if taken.any():
                row, col = np.argwhere(taken)[0]
                other = list(masks)[int(labels[row, col]) - 1]
                raise _fail(f"regions {other!r} and {name!r} overlap (at row {row}, column {col}): a pixel belongs "
                            "to one region")
            labels[m] = label
        return cls(labels, names={name: label for label, name in enumerate(masks, start=1)})

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.labels.shape)

    def mask(self, label: int) -> np.ndarray:
        """The pixels of one region (bool, one byte a pixel)."""
        return self.labels == label

    def union(self) -> np.ndarray:
        """The pixels of every region: what the whole is scored over."""
        return self.labels != 0

    def check_shape(self, shape: tuple[int, ...]) -> None:
        if self.shape != tuple(shape):
            raise _fail(f"the label image has shape {self.shape}, the frames {tuple(shape)}", ShapeError)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Regions):
            return NotImplemented
        return self.names == other.names and np.array_equal(self.labels, other.labels)

    __hash__ = None  # type: ignore[assignment]

    def __getstate__(self) -> tuple:
        return self.labels, self.names, self.pixels

    def __setstate__(self, state: tuple) -> None:
        self.labels, self.names, self.pixels = state

    def __repr__(self) -> str:
        parts = ", ".join(f"{name}: label {label}, {self.pixels[name]} px" for label, name in self.names.items())
        return f"Regions({self.shape[0]}×{self.shape[1]}; {parts})"


def as_regions(value: Any) -> Regions:
    """``evaluate``'s ``regions=``: a :class:`Regions`, a label image, or ``{name: bool array}``."""
    if isinstance(value, Regions):
        return value
    if isinstance(value, Mapping):
        return Regions.from_masks(value)
    return Regions(value)


def scored_mask(mask: Any, regions: Regions | None, shape: tuple[int, ...]) -> Any:
    """The pixels the whole is scored over: ``mask`` (an array, or a mask file's path) within the
    union of ``regions``."""
    if isinstance(mask, (str, os.PathLike)):
        from .masks import scoring_mask

        from_file = scoring_mask(mask, None, (int(shape[0]), int(shape[1])))
        assert from_file is not None  # None only without a mask and a roi
        mask = from_file.values
    if regions is None:
        return mask
    regions.check_shape(shape)
    union = regions.union()
    if mask is None:
        return union
    given = np.asarray(mask)
    if given.shape != union.shape:
        raise ShapeError(f"mask has shape {given.shape}, frames have {union.shape}", option="mask")
    union &= given.astype(bool, copy=False)
    if not union.any():
        raise _fail("no labelled pixel lies within mask= (the pixels it keeps all carry label 0)")
    return union


# --------------------------------------------------------------------------- statistics of a mask
def with_psnr_peak(stats: _stats.PairStats, span: float | None, components: tuple, config: ScoringConfig,
                   where: str) -> _stats.PairStats:
    """``stats`` with the configured PSNR peak (:func:`irfidelity.scoring.psnr_peak`; ``span``:
    the real frame's range over the scored pixels) when PSNR is computed."""
    if "psnr" not in components:
        return stats
    # stats.peak is the default peak (2**bits - 1, the dtype's): psnr_peak needs it only without a peak
    peak = psnr_peak(config, stats.peak, span, where=where)
    return stats if peak == stats.peak else stats.with_peak(peak)


def masked_stats(real: Any, sim: Any, components: tuple, config: ScoringConfig, mask: Any, *, bits: int | None,
                 peak: float | None, where: str = "real frame") -> tuple[_stats.PairStats, float | None]:
    """The statistics of a pair over ``mask`` (one Rust pass, GIL released) with the PSNR peak
    resolved, and the real frame's range over the scored pixels."""
    st = _stats.pair_stats(real, sim, bits=bits, peak=peak, bins=config.bins, hist_range=config.hist_range,
                           mask=mask, need=components, nonfinite=config.nonfinite)
    span = _stats.real_range(real, mask, config.nonfinite, st) if "psnr" in components else None
    return with_psnr_peak(st, span, components, config, where), span


# --------------------------------------------------------------------------- scoring the regions
def _check_budget(regions: Regions, sources: Mapping[str, Any], widened: bool, max_bytes: int | None) -> None:
    """The plan of scoring the regions: what the pair holds, the label image, one region's mask,
    the real frame as float64 (registered pairs) and the statistics' masks."""
    held = budget.nbytes(*(sources.get(k) for k in ("real", "sim", "sim_unregistered", "mask")), regions.labels)
    per_pixel = 1 + budget.SCORING_BYTES + (budget.WIDENED_BYTES if widened else 0)
    budget.check("scoring regions", regions.shape, held + per_pixel * regions.labels.size, max_bytes)


def scored_frames(sources: Mapping[str, Any], config: ScoringConfig, max_bytes: int | None
                  ) -> tuple[np.ndarray, np.ndarray, int | None, float | None]:
    """The frames a pair's pixels (or its regions) are scored on, with the bit depth and peak
    their statistics take: as given, or for a registered pair the real frame as float64 beside
    the resampled one (the integer levels were checked against ``bits`` by the pair's pass; the
    float64 copy is planned against ``max_bytes`` with what the pair holds)."""
    real, sim = np.asarray(sources["real"]), np.asarray(sources["sim"])
    if sources.get("registration") is None:
        return real, sim, config.bits, config.numeric_peak
    peak, _ = _stats.peak_and_valid(real.dtype, config.bits, config.numeric_peak)
    if real.dtype != np.float64:
        held = budget.nbytes(*(sources.get(k) for k in ("real", "sim", "sim_unregistered", "mask")))
        budget.check("the real frame as float64 beside the resampled one", real.shape, held + 8 * real.size, max_bytes)
    return real.astype(np.float64, copy=False), sim, None, peak


def registered_union(regions: Regions, sources: dict, components: tuple, config: ScoringConfig,
                     max_bytes: int | None) -> tuple[_stats.PairStats, float | None]:
    """The statistics of a registered pair over the union of ``regions`` within the overlap (the
    pair's scored pixels become those), and the real frame's range over them."""
    real, sim, bits, peak = scored_frames(sources, config, max_bytes)
    _check_budget(regions, sources, real is not sources["real"], max_bytes)
    sources["mask"] = within = regions.union() & np.asarray(sources["mask"], dtype=bool)
    if not within.any():
        raise _fail("no labelled pixel lies in the overlap of the registered frames")
    return masked_stats(real, sim, components, config, within, bits=bits, peak=peak)


def _region_scored(regions: Regions, label: int, scored: Any) -> np.ndarray:
    """One region's mask within the pixels the pair scored; an error when that leaves none."""
    mask = regions.mask(label)
    if scored is not None:
        mask &= np.asarray(scored, dtype=bool)
    if not mask.any():
        raise _fail(f"region {regions.names[label]!r} (label {label}) has no pixel left to score (within mask= and, "
                    "for a registered pair, the overlap of the frames)")
    return mask


def _own_scores(real: np.ndarray, sim: np.ndarray, mask: np.ndarray, plan: tuple, config: ScoringConfig,
                weights: Weights, pair_metrics: Mapping[str, Any], bits: int | None, peak: float | None,
                name: str) -> tuple[dict[str, float], dict[str, Any], float | None]:
    """A region's own components and metrics — the image components over its pixels, and the
    temperature errors in a unit — and the real frame's range over them."""
    components: dict[str, float] = {}
    metrics: dict[str, Any] = {}
    span = None
    if plan:
        st, span = masked_stats(real, sim, plan, config, mask, bits=bits, peak=peak, where=f"region {name!r}")
        components, metrics = image_components(st, plan, config)
    if config.unit is not None:
        errors = TemperatureErrors.of_frames(real, sim, mask=mask, tolerance=tolerance_for(config, pair_metrics),
                                             unit=str(config.unit))
        own, temperature_metrics = temperature_scores(errors, weights)
        components.update(own)
        metrics.update(temperature_metrics)
    return components, metrics, span


def _entry(label: int, pixels: int, score: Any, metrics: dict, ceiling: Any) -> dict:
    """A region's entry of ``report.regions``."""
    from .ceiling import relative_to

    return {"label": label, "pixels": pixels, "fidelity": score.fidelity, "grade": score.grade,
            "components": dict(score.components), "component_grades": dict(score.grading.component_grades),
            "membership": dict(score.grading.membership), "metrics": metrics, "verdict": score.verdict.to_dict(),
            "ceiling": ceiling, "relative": relative_to(ceiling, score.components)}


def score_regions(regions: Regions, sources: Mapping[str, Any], plan: tuple, config: ScoringConfig,
                  weights: Weights, pair_components: Mapping[str, float], pair_metrics: Mapping[str, Any], *,
                  ceiling: Any = None, ceiling_source: str | None = None, real_ref: Any = None,
                  unassessed: Mapping[str, str] | None = None, max_bytes: int | None = None) -> dict[str, dict]:
    """Each region's entry of ``report.regions`` (labels ascending): its image components over
    its own pixels, the pair's camera components, eq. (15) and the grade.

    ``sources`` are the pair's frames as scored (``real``, ``sim``, ``mask``, ``registration``);
    ``plan`` the image components; ``ceiling`` the pair's ceiling (given, or from the real
    camera's noise; ``ceiling_source`` says which), or ``real_ref`` the second real frame from
    which each region's own ceiling is measured; ``unassessed`` what the pair could not assess,
    said in each region's verdict too.
    """
    from .ceiling import pair_ceiling

    real, sim, bits, peak = scored_frames(sources, config, max_bytes)
    _check_budget(regions, sources, real is not sources["real"], max_bytes)
    camera = {k: v for k, v in pair_components.items() if k not in OWN_COMPONENTS}
    out: dict[str, dict] = {}
    for label, name in regions.names.items():
        mask = _region_scored(regions, label, sources.get("mask"))
        with warnings.catch_warnings():  # the pair's PeakWarning covers its regions: the same peak
            warnings.simplefilter("ignore", PeakWarning)
            own, metrics, span = _own_scores(real, sim, mask, plan, config, weights, pair_metrics, bits, peak, name)
        region_ceiling = ceiling
        if real_ref is not None and plan:
            region_ceiling = pair_ceiling(np.asarray(sources["real"]), real_ref, plan, config, mask=mask,
                                          peak=metrics.get("psnr_peak"))
        del mask  # one region's mask at a time (the memory plan counts one)
        camera_metrics = {k: v for k, v in pair_metrics.items() if k not in metrics}
        score = score_components({**camera, **own}, {**camera_metrics, **metrics}, weights, config,
                                 scene_range=span, ceiling=region_ceiling,
                                 ceiling_source="real_ref" if real_ref is not None and plan else ceiling_source,
                                 unassessed=unassessed)
        out[name] = _entry(label, regions.pixels[name], score, metrics, region_ceiling)
    return out


# --------------------------------------------------------------------------- flat forms
def _own(entry: Mapping[str, Any]) -> list[str]:
    from .fuzzy import COMPONENTS

    return [c for c in COMPONENTS if c in OWN_COMPONENTS and c in (entry.get("components") or {})]


def region_columns(regions: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The CSV columns of a pair's regions, after the pair's own: for each region (labels
    ascending) ``region_<name>_<key>`` for :data:`irfidelity.schema.REGION_COLUMNS`' keys, its
    own metrics (schema order) and ``f_<component>`` of its own components."""
    from .schema import REGION_COLUMNS, metric_names

    columns = []
    for name, entry in regions.items():
        metrics = entry.get("metrics") or {}
        own = [k for k in ("n", "masked", "nonfinite") if k in metrics]
        keys = ([k for k, _, _ in REGION_COLUMNS[:2]] + own + [m for m in metric_names(_own(entry) + ["radiometry"])
                                                              if m in metrics]
                + [f"f_{c}" for c in _own(entry)] + [k for k, _, _ in REGION_COLUMNS[2:]])
        columns += [f"region_{name}_{key}" for key in keys]
    return columns


def region_values(regions: Mapping[str, Mapping[str, Any]]) -> list[Any]:
    """The values of :func:`region_columns`, in its order."""
    values = []
    for name, entry in regions.items():
        metrics, components = entry.get("metrics") or {}, entry.get("components") or {}
        for column in region_columns({name: entry}):
            key = column[len(f"region_{name}_"):]
            if key.startswith("f_"):
                values.append(components.get(key[2:]))
            elif key in metrics:
                values.append(metrics[key])
            else:
                values.append(entry.get(key))
    return values

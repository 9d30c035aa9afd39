"""Exception and warning classes.

Every error raised by irfidelity derives from :class:`FidelityError`, itself a
``ValueError`` so that callers who only know the standard library still catch it.
The Rust core raises these same classes (``rust/binding/mod.rs`` maps its error
kinds here), so there is one hierarchy whatever layer failed.

Every warning derives from :class:`FidelityWarning` and is defined here; the modules that
issue one re-export it (``irfidelity.curves.edge.EdgeWarning`` is this module's class).
"""

from __future__ import annotations

__all__ = ["FidelityError", "ConfigError", "FrameError", "ShapeError", "RangeError", "RegistrationError", "FidelityWarning",
           "PeakWarning", "RegistrationWarning", "EdgeWarning", "CurveUnitsWarning", "NoiseWarning",
           "AHPConsistencyWarning", "BarWarning", "BarClippingWarning", "BarSamplingWarning", "BarPolarityWarning",
           "ColtmanWarning", "MRTDWarning", "RadiometryWarning", "ShortRecordingWarning", "JudgementWarning"]


class FidelityError(ValueError):
    """Base class of every irfidelity error.

    ``option`` names the option (configuration field or keyword argument) the message is
    about, when there is one; the command line uses it to name its flag.
    """

    def __init__(self, *args: object, option: str | None = None):
        super().__init__(*args)
        self.option = option


class ConfigError(FidelityError):
    """A scoring-option value (a :class:`~irfidelity.ScoringConfig` field, a configuration file's
    or a function's keyword) that is not valid: ``"bins: expected ...; got 0"``. ``option`` is
    the field and ``detail`` the message without it (the command line prefixes its flag)."""

    def __init__(self, field_name: str, message: str):
        super().__init__(f"{field_name}: {message}", option=field_name.split(".")[0])
        self.detail = message


class FrameError(FidelityError, OSError):
    """A frame file is unreadable, corrupt, unsupported or oversized.

    The message names the path and the reason. Also an ``OSError`` so that
    ``except OSError`` around file handling keeps working.
    """


class ShapeError(FidelityError):
    """Frames (or masks) whose shapes or dtypes do not match, or are not 2-D."""


class RangeError(FidelityError):
    """Values outside what was declared: above ``2**bits - 1``, negative, or non-finite."""


class RegistrationError(FidelityError):
    """A frame pair that cannot be registered: flat frames, no overlap, a transform beyond
    the allowed search range, or an ambiguous correlation peak. The message says which."""


class FidelityWarning(UserWarning):
    """Base class of irfidelity's warnings: a result that is computed but may mislead
    (a PSNR peak far above the scene's range, a low-contrast edge, a low registration
    confidence, ...). Filter them all with ``warnings.simplefilter("error", FidelityWarning)``.

    ``option`` names the option that would change the outcome, when there is one.
    """

    def __init__(self, *args: object, option: str | None = None):
        super().__init__(*args)
        self.option = option


class PeakWarning(FidelityWarning):
    """The PSNR peak is so far above the real frame's range that the ``psnr`` component is
    pinned near 1 for any simulated frame whose errors stay within the scene's range."""


class RegistrationWarning(FidelityWarning):
    """A registration was found but is unsure: a rival transform matches nearly as well
    (confidence below :data:`irfidelity.registration.LOW_CONFIDENCE`). Check
    ``reg.confidence`` before trusting the metrics computed on the registered pair."""


class EdgeWarning(FidelityWarning):
    """A slanted-edge measurement that ran, but whose conditions make the MTF doubtful:
    clipped pixels, low contrast, an edge angle near 0°/45° or a critical angle, empty ESF bins."""


class CurveUnitsWarning(FidelityWarning):
    """Two curves are compared although the unit of an axis is unknown on both: the comparison
    assumes they agree (the user's responsibility)."""


class NoiseWarning(FidelityWarning):
    """A 3-D noise result that may mislead: a scene that is not uniform (gradient or object),
    or samples at the ends of the valid range (saturated or clipped pixels)."""


class AHPConsistencyWarning(FidelityWarning):
    """An AHP comparison matrix whose consistency ratio exceeds the threshold (Saaty: 0.1):
    the judgements contradict each other too much for the weights to be trusted."""


class BarWarning(FidelityWarning):
    """A bar-target reading (:func:`irfidelity.curves.ctf_from_bars`) that ran, but whose
    conditions make the CTF doubtful; the subclasses say which."""


class BarClippingWarning(BarWarning):
    """Pixels of the bar target sit at the clipping level (saturated bars or gaps): the bar
    modulation is biased."""


class BarSamplingWarning(BarWarning):
    """Bars too narrow for the bar-modulation method (under about two pixels wide): the
    modulation depends on where the samples fall on the bars; the fundamental-amplitude ratio
    does not."""


class BarPolarityWarning(BarWarning):
    """Inverted polarity: the bar centres read darker than the gaps in the target's own
    polarity (contrast reversal, spurious resolution), or the target's polarity contradicts the
    sign of the temperature difference it was given with."""


class ColtmanWarning(FidelityWarning):
    """A CTF ↔ MTF conversion (Coltman's series) had to take the curve as 0 beyond its last
    frequency although it has not fallen to 0 there: values above a third of that frequency
    miss terms."""


class MRTDWarning(FidelityWarning):
    """Frequencies left out of an MRTD curve: an MTF too small for the model, or bars that no
    frame resolved at the threshold."""


class RadiometryWarning(FidelityWarning):
    """Some counts (or temperatures) lie outside the radiometric calibration's domain (no finite
    temperature above 0 K) and became NaN; the message counts them."""


class ShortRecordingWarning(FidelityWarning):
    """Too few frames for honest intervals over frames: they make fewer than five blocks of the
    length their correlation asks for, so the block bootstrap's intervals are likely too narrow
    and its tests and P(first) too sure (:func:`irfidelity.bootstrap.short_recording_note`)."""


class JudgementWarning(FidelityWarning):
    """Experts' judgements that the fitted weights cannot speak for: an expert whose held-out
    judgements the negated weights predict better than the weights (they judge by the opposite
    criterion, :func:`irfidelity.fuzzy.fit_weights`)."""

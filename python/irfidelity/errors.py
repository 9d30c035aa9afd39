"""Exception and warning classes.

Every error raised by irfidelity derives from :class:`FidelityError`, itself a
``ValueError`` so that callers who only know the standard library still catch it.
The Rust core raises these same classes (``rust/binding/mod.rs`` maps its error
kinds here), so there is one hierarchy whatever layer failed.
"""

from __future__ import annotations

__all__ = ["FidelityError", "FrameError", "ShapeError", "RangeError", "RegistrationError", "FidelityWarning",
           "PeakWarning", "RadiometryWarning"]


class FidelityError(ValueError):
    """Base class of every irfidelity error.

    ``option`` names the option (configuration field or keyword argument) the message is
    about, when there is one; the command line uses it to name its flag.
    """

    def __init__(self, *args: object, option: str | None = None):
        super().__init__(*args)
        self.option = option


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


class RadiometryWarning(FidelityWarning):
    """Some counts (or temperatures) lie outside the radiometric calibration's domain (no finite
    temperature above 0 K) and became NaN; the message counts them."""

"""The command line's arguments: ``irfidelity score``, ``irfidelity demo``, ``irfidelity config``,
``irfidelity targets`` (``rank`` and ``weights``: :mod:`.rank`)."""

from __future__ import annotations

import argparse
from typing import NoReturn

from .._version import __version__
from ..budget import parse_size
from ..config import MISSING_MODES, NONFINITE_MODES, PAIRING_RULES, REGISTRATION_MODELS
from ..curves.table import parse_columns, parse_where
from ..errors import ConfigError, FidelityError
from ..image_writers import FORMATS
from ..registration import DEFAULT_METHOD, METHODS
from ..stats import HIST_RANGES, bins_value
from .flags import CALIBRATION_FLAGS
from .rank import add_rank, add_weights
from .targets import KINDS

__all__ = ["build_parser", "EXIT_OK", "EXIT_USAGE", "EXIT_FAILED_FRAMES", "EXIT_NOT_ACCEPTED"]

#: Exit statuses: 0 scored (and accepted, with ``--spec``); 2 bad usage or input (1 is Python's
#: own for an uncaught error, 130 an interrupt); 3 a sequence finished but some frames failed;
#: 4 scored, but not accepted by the ``--spec`` acceptance specification.
EXIT_OK, EXIT_USAGE, EXIT_FAILED_FRAMES, EXIT_NOT_ACCEPTED = 0, 2, 3, 4


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, no usage dump
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _int_from(lowest: int):
    """An argparse type: an integer >= ``lowest``."""
    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            n = lowest - 1
        if n < lowest:
            raise argparse.ArgumentTypeError(f"expected an integer >= {lowest}, got {text!r}")
        return n

    return parse


_positive_int, _non_negative_int = _int_from(1), _int_from(0)


def _positive_float(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        x = float("nan")
    if not x > 0 or x == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return x


def _peak(text: str) -> float | str:
    return "range" if text == "range" else _positive_float(text)


def _bins(text: str) -> int | str:
    """``--bins``: checked by the library's one check of ``bins``, with its message."""
    try:
        value: object = int(text)
    except ValueError:
        value = text
    try:
        return bins_value(value)
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(exc.detail) from None


def _hist_range(text: str) -> str | tuple[float, float]:
    if text in HIST_RANGES:
        return text
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {', '.join(HIST_RANGES)} or LO,HI; got {text!r}") from None
    return (lo, hi)


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def _calibration(text: str) -> dict[str, float]:
    """``NAME=VALUE,...``: calibration fields, or a linear gain and offset."""
    out: dict[str, float] = {}
    for item in text.split(","):
        name, sep, value = item.partition("=")
        if not sep:
            raise argparse.ArgumentTypeError(f"expected NAME=VALUE items (gain=0.04,offset=-273.15 or "
                                             f"planck_r1=...,planck_b=...), got {item!r}")
        out[name.strip()] = _number(value.strip())
    return out


def _argument_type(parse):
    """An argparse type from a parser that raises FidelityError."""
    def convert(text: str):
        try:
            return parse(text)
        except FidelityError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    return convert


_columns, _where, _size = _argument_type(parse_columns), _argument_type(parse_where), _argument_type(parse_size)


def _add_score(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser(
        "score", help="score a simulated frame (or sequence) against the real one",
        description="Score SIM against REAL: components (MTF, SiTF, PSNR, NMI, SSIM), weights, fidelity "
                    "(eq. 15) and grade. REAL and SIM are two frame files (PNG, TIFF, EXR, .npy), or two "
                    "sequences: directories, glob patterns or multi-page TIFFs (scored pair by pair and pooled).",
        epilog="Options left out keep the value of --config, or the default. "
               "Exit status: 0 scored (and accepted, with --spec), 2 bad usage or input (a bad --spec included), "
               "3 some frames of a sequence failed, 4 scored but not accepted by --spec.")
    s.add_argument("real", metavar="REAL", help="real camera frame, or a directory / glob / multi-page TIFF")
    s.add_argument("sim", metavar="SIM", help="simulated frame, or a directory / glob / multi-page TIFF")
    s.add_argument("--config", metavar="FILE", help="scoring configuration (TOML or JSON; see 'irfidelity config')")
    s.add_argument("--spec", metavar="FILE",
                   help="acceptance specification (TOML: the required components, the least grade of each and "
                        "optionally their tolerances, docs/interpretation.md): its tolerances are applied, each "
                        "requirement is checked and printed PASS/FAIL; exit status 4 when not accepted")
    g = s.add_argument_group("what decides the score")
    g.add_argument("--bits", type=_positive_int, metavar="N",
                   help="bit depth of integer frames: values must be <= 2^N-1; default PSNR peak 2^N-1 "
                        "(--peak overrides the peak; --bits still bounds the values)")
    g.add_argument("--peak", type=_peak, metavar="X|range",
                   help="PSNR peak: a number (needed for float frames), or 'range' (the real frame's max - min); "
                        "with --bits, the values are still bounded by 2^N-1")
    g.add_argument("--weights", metavar="SPEC",
                   help="balanced (default, 1/5 each) | performance | image_quality | "
                        "'mtf=..,sitf=..,psnr=..,nmi=..,ssim=..,noise=..,radiometry=..' (unnamed components 0; "
                        "sum 1)")
    g.add_argument("--bins", type=_bins, metavar="N|levels",
                   help="histogram bins for NMI (default 256), or 'levels' (one bin per grey level)")
    g.add_argument("--hist-range", type=_hist_range, metavar="each|data|full|LO,HI",
                   help="histogram edges: each frame's own robust range, the simulated one's carried by their gain "
                        "and offset (default); both frames' min..max (the paper's); 0..peak; or given")
    g.add_argument("--missing", choices=MISSING_MODES,
                   help="a weighted component without inputs: drop it and renormalise the other weights "
                        "(default; shown as skipped), or fail (raise)")
    g.add_argument("--nonfinite", choices=NONFINITE_MODES, help="NaN/Inf in float frames: fail (default) or mask")
    g.add_argument("--tolerance", action="append", metavar="NAME=E,G,F",
                   help="the limits of excellent, good and fair for one tolerance (repeatable): mtf50, sitf_slope "
                        "(mismatch), noise_ratio, rms_error (fraction of the scene's range), nmi, ssim (fraction of "
                        "the ceiling), radiometry (temperature tolerances); e.g. mtf50=0.03,0.08,0.15 "
                        "(docs/interpretation.md)")
    v = s.add_argument_group("what is scored")
    v.add_argument("--real-ref", metavar="FILE",
                   help="a second real frame of the scene: the real-vs-real ceiling NMI and SSIM are graded against "
                        "(single pairs)")
    v.add_argument("--mask", metavar="PATH", help="score only the pixels where this PNG/NPY/TIFF is non-zero (on the "
                                                  "real frame's grid; a sequence: in every frame pair)")
    v.add_argument("--roi", metavar="Y0:Y1,X0:X1", help="score only this region (rows Y0..Y1-1, columns X0..X1-1)")
    v.add_argument("--regions", metavar="PATH",
                   help="a label image (PNG/NPY/TIFF: 0 not scored, 1..255 a region): each region scored on its own "
                        "beside the whole (their union)")
    v.add_argument("--region-names", metavar="NAME,...|NAME=LABEL,...",
                   help="names of the --regions labels: in label order (target,background) or by label "
                        "(target=1,background=2)")
    t = s.add_argument_group("temperatures (radiometric files; float frames are taken as already in the unit)")
    t.add_argument("--unit", choices=("K", "C"), help="score temperatures in kelvin or degrees Celsius: adds the "
                                                     "temperature errors and the opt-in 'radiometry' component")
    for dest, (_, metavar, text) in CALIBRATION_FLAGS.items():
        t.add_argument("--" + dest.replace("_", "-"), type=_number, metavar=metavar,
                       help=text + " (overrides a radiometric file's value)")
    t.add_argument("--calibration", type=_calibration, metavar="NAME=V,...",
                   help="calibration of integer frames without one: gain=G,offset=O (temperature = G*count + O) "
                        "or the Planck constants planck_r1,planck_r2,planck_b,planck_f,planck_o")
    t.add_argument("--temperature-tolerance", type=_positive_float, metavar="K",
                   help="error counted as within tolerance and scale of the radiometry component (default: the "
                        "real camera's NETD when measured, else 1 K)")
    c = s.add_argument_group("channels")
    c.add_argument("--channel", metavar="C", help="channel of both frames' files (e.g. EXR 'Y', PNG 'R')")
    c.add_argument("--real-channel", metavar="C", help="channel of the real frames only")
    c.add_argument("--sim-channel", metavar="C", help="channel of the simulated frames only")
    c.add_argument("--edge-channel", metavar="C", help="channel of both sides' multi-channel edge images")
    c.add_argument("--real-edge-channel", metavar="C", help="channel of the real edge image only")
    c.add_argument("--sim-edge-channel", metavar="C", help="channel of the simulated edge image only")
    k = s.add_argument_group("camera curves (compared once; with sequences they count for every frame)")
    k.add_argument("--real-mtf", metavar="CSV|IMG", help="real MTF: a curve CSV (frequency, MTF) or an edge image")
    k.add_argument("--sim-mtf", metavar="CSV|IMG", help="simulated MTF: a curve CSV or an edge image")
    k.add_argument("--real-edge", metavar="IMG", help="real slanted-edge image (MTF by ISO 12233 e-SFR)")
    k.add_argument("--sim-edge", metavar="IMG", help="simulated slanted-edge image")
    k.add_argument("--real-sitf", metavar="CSV", help="real SiTF curve (temperature difference, signal)")
    k.add_argument("--sim-sitf", metavar="CSV", help="simulated SiTF curve")
    for side in ("real", "sim"):
        for kind in ("mtf", "sitf"):
            k.add_argument(f"--{side}-{kind}-columns", type=_columns, metavar="X,Y",
                           help=f"the two columns of the {side} {kind.upper()} CSV (names or 0-based indices)")
            k.add_argument(f"--{side}-{kind}-where", type=_where, metavar="NAME=VALUE",
                           help=f"only the rows of the {side} {kind.upper()} CSV where column NAME equals VALUE")
    k.add_argument("--edge-fit-order", type=_int_from(1), metavar="N", choices=range(1, 6),
                   help="order of the edge-location fit of slanted-edge images: 5 (default, ISO 12233:2023) .. 1 "
                        "(a straight line, ISO 12233:2014)")
    k.add_argument("--ifov", type=_positive_float, metavar="MRAD", dest="ifov_mrad",
                   help="instantaneous field of view of a pixel, to convert cycles/pixel <-> cycles/mrad")
    k.add_argument("--pixel-pitch", type=_positive_float, metavar="UM", dest="pixel_pitch_um",
                   help="detector pixel pitch, to convert cycles/pixel <-> line pairs/mm")
    k.add_argument("--focal-length", type=_positive_float, metavar="MM", dest="focal_length_mm",
                   help="focal length, to convert cycles/mrad <-> line pairs/mm")
    n = s.add_argument_group("sensor noise (the opt-in 'noise' component: give it a weight in --weights; the real "
                             "camera's alone also sets the ceiling)")
    n.add_argument("--real-noise", metavar="DIR|TIF", help="frames of a uniform source (blackbody) from the real "
                                                          "camera: a directory, glob or multi-page TIFF; without "
                                                          "--real-ref, its 3-D noise sets the ceiling NMI and SSIM are "
                                                          "graded against (for a sequence, instead of consecutive "
                                                          "frames)")
    n.add_argument("--sim-noise", metavar="DIR|TIF", help="the same from the simulator")
    n.add_argument("--noise-detrend", choices=("plane",), help="remove a gradient (plane) across the uniform "
                                                               "source's frames before measuring their noise")
    n.add_argument("--noise-roi", metavar="Y0:Y1,X0:X1", help="measure the noise within this box of the uniform "
                                                               "source's frames (rows, then columns; 0-based, end "
                                                               "excluded)")
    b = s.add_argument_group("bar targets (the opt-in 'mrtd' component: give it a weight in --weights)")
    b.add_argument("--real-bars", metavar="DIR", help="frames of bar targets from the real camera, listed with their "
                                                     "frequency and ΔT in DIR/bars.csv (docs/bars.md)")
    b.add_argument("--sim-bars", metavar="DIR", help="the same from the simulator")
    r = s.add_argument_group("registration and sequences")
    r.add_argument("--register", choices=REGISTRATION_MODELS, metavar="MODEL",
                   help="align the simulated frame to the real one first and score the overlap: translation, "
                        "rigid or similarity (a sequence is registered once, on its first pair)")
    r.add_argument("--register-method", choices=METHODS, metavar="METHOD",
                   help=f"how to register: {', '.join(METHODS)} (default {DEFAULT_METHOD}; docs/registration.md)")
    r.add_argument("--register-each", action="store_true", default=None,
                   help="sequences: register every frame pair on its own (with --register's model)")
    r.add_argument("--max-delay", type=_non_negative_int, metavar="N",
                   help="sequences: find the frame offset between the sequences within +-N frames and pair "
                        "frames by position offset by it")
    r.add_argument("--pair-by", choices=PAIRING_RULES,
                   help="sequences: pair frames by file name (auto, the default, when names match) or by order")
    r.add_argument("--pages", metavar="SEL",
                   help="sequences: frames to score, by position: START:STOP[:STEP] or i,j,k (0-based)")
    o = s.add_argument_group("output and running")
    o.add_argument("--json", metavar="PATH|-", help="write the report as JSON to PATH, or to stdout with '-'")
    o.add_argument("--csv", metavar="PATH", help="write one row per frame pair as CSV (sequences: streamed)")
    o.add_argument("--report", metavar="PATH", help="write a self-contained HTML report")
    o.add_argument("--save-config", metavar="PATH", help="write the scoring configuration used (TOML or JSON)")
    o.add_argument("--resume", action="store_true", help="sequences: keep the frames already scored in --csv")
    o.add_argument("--ci", action="store_true", help="sequences: also the 0.95 intervals of the pooled fidelity and "
                                                     "components (block bootstrap over frames; report.ci)")
    o.add_argument("--workers", type=_positive_int, metavar="N", help="sequences: parallel workers")
    o.add_argument("--max-memory", type=_size, metavar="SIZE",
                   help="memory budget of the run, e.g. 2G, 512M or bytes: a sequence's workers share it (each "
                        "pair gets SIZE / workers), a single pair gets all of it; work that would need more is "
                        "refused before it starts (a frame's error row in a sequence). Default: 2 GiB per pair")
    o.add_argument("--max-pixels", type=_positive_int, metavar="N",
                   help="decode frames of up to N pixels (default 67108864, one 8192 x 8192 frame): a larger "
                        "frame is refused before it is decoded")
    o.add_argument("--no-progress", action="store_true", help="sequences: no progress display")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="irfidelity",
                description="Fidelity of an infrared camera simulator against the real camera "
                            "(fuzzy-logic framework, Acta Photonica Sinica 41(5):547, 2012).")
    p.add_argument("--version", action="version", version=f"irfidelity {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    _add_score(sub)
    add_rank(sub, {"bits": _positive_int, "peak": _peak, "bins": _bins, "positive_int": _positive_int, "size": _size})
    add_weights(sub)
    d = sub.add_parser(
        "demo", help="score a toy simulator on bundled real infrared data",
        description="Scores a simulated frame made by a simple camera model (Gaussian blur, gain/offset, "
                    "seeded noise) against a real FLIR Lepton frame, a blurred slanted-edge crop against "
                    "the real crop (MTF), and a Planck in-band model against a measured Jade LWIR "
                    "calibration (SiTF). No arguments needed.")
    d.add_argument("--json", metavar="PATH|-", help="also write the report as JSON to PATH, or only JSON to stdout "
                                                   "with '-'")
    d.add_argument("--report", metavar="PATH", help="also write a self-contained HTML report")
    c = sub.add_parser("config", help="print (or write) the default scoring configuration",
                       description="Print the default scoring configuration as TOML, or write it to PATH: a "
                                   "starting point for 'irfidelity score --config PATH'.")
    c.add_argument("path", nargs="?", metavar="PATH", help="write here instead of printing (.toml or .json)")
    _add_targets(sub)
    return p


def _add_targets(sub: argparse._SubParsersAction) -> None:
    t = sub.add_parser(
        "targets", help="write bar-target or slanted-edge images",
        description="Write ideal four-bar or three-bar targets (7:1 bars; one image per frequency, listed in "
                    "OUT/bars.csv) or a slanted edge, as a simulator or a collimator is fed: exact pixel area "
                    "averages, optionally through a Gaussian blur.")
    t.add_argument("out", metavar="OUT", help="directory to write into (created when missing)")
    t.add_argument("--kind", choices=tuple(KINDS), default="four-bar", help="four-bar (default), three-bar or edge")
    t.add_argument("--frequency", metavar="F[,F...]", help="bar frequencies, cycles/pixel (one image each)")
    t.add_argument("--size", metavar="ROWS,COLS", default="128,128", help="image size (default 128,128)")
    t.add_argument("--orientation", choices=("vertical", "horizontal"), default="vertical",
                   help="vertical bars or edge (intensity changes along a row; default) or horizontal")
    t.add_argument("--phase", type=float, default=0.0, metavar="PX", help="shift across the bars, pixels")
    t.add_argument("--angle", type=float, default=5.0, metavar="DEG", help="tilt of the slanted edge (default 5)")
    t.add_argument("--levels", metavar="BACKGROUND,BAR", help="background and bar levels (default 16384,49152 "
                                                              "for PNG, 0,1 otherwise)")
    t.add_argument("--blur", type=float, metavar="SIGMA", help="Gaussian blur sigma, pixels (default none)")
    t.add_argument("--format", choices=tuple(FORMATS), default="png",
                   help="png (16-bit grey, default), tiff (float32) or npy (float64)")

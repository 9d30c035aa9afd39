"""Each rule is checked in one place (issue 26, "validate at the boundary once"), so every entry
point gives the same error class and message for the same mistake: ``bins`` (one rule for
ScoringConfig, pair_stats and the metrics on it, and ``--bins``), a pair's shapes (one check in
the Rust binding, reached by register, evaluate, score_sequence and the command line), the
dtype names (one list in Rust, ``_core.SUPPORTED_DTYPES``), the registration models and methods
(``_core.REGISTRATION_MODELS``/``METHODS``, their messages built from them), and the PSNR peak
resolved once per evaluate."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import irfidelity as irf
from irfidelity import _core
from irfidelity import stats as stats_module
from irfidelity.alignment import score_registered
from irfidelity.cli import main
from irfidelity.errors import ConfigError, FidelityError, ShapeError
from irfidelity.frames import FRAME_DTYPES
from irfidelity.stats import PairRequest, bins_value, full_range

BINS_MESSAGE = "bins: expected an integer in 1..1048576 or 'levels'; got {}"


def frames(shape=(40, 48)) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(26)
    real = rng.integers(1000, 3000, size=shape).astype(np.uint16)
    return real, (real.astype(np.int64) + rng.integers(-20, 21, size=shape)).astype(np.uint16)


def cli(capsys, *argv: str) -> tuple[int, str]:
    """The exit status and standard error of ``irfidelity ARGV`` (argparse's errors included)."""
    try:
        rc = main(list(argv))
    except SystemExit as exc:
        rc = exc.code
    return rc, capsys.readouterr().err


# --------------------------------------------------------------------------- bins
BINS_CALLS = {
    "ScoringConfig": lambda bins: irf.ScoringConfig(bins=bins),
    "evaluate": lambda bins: irf.evaluate(*frames(), bins=bins, weights="nmi=1"),
    "pair_stats": lambda bins: irf.pair_stats(*frames(), bins=bins),
    "nmi": lambda bins: irf.stats.nmi(*frames(), bins=bins),
    "bins_value": bins_value,
}


BAD_BINS = [0, -3, (1 << 20) + 1, True, 2.0, "lvls", None]


# evaluate's keyword bins=None means "not given" (the configuration's bins)
@pytest.mark.parametrize("entry,bins", [(entry, bins) for entry in sorted(BINS_CALLS) for bins in BAD_BINS
                                        if not (entry == "evaluate" and bins is None)])
def test_every_entry_refuses_bad_bins_with_one_message(entry, bins):
    with pytest.raises(ConfigError) as caught:
        BINS_CALLS[entry](bins)
    assert str(caught.value) == BINS_MESSAGE.format(repr(bins))
    assert caught.value.option == "bins" and caught.value.detail in str(caught.value)


def test_evaluate_with_bins_none_keeps_the_default():
    assert irf.evaluate(*frames(), weights="nmi=1").config.bins == 256


@pytest.mark.parametrize("bins", [1, 64, np.int64(64), np.uint16(300), 1 << 20, "levels"])
def test_every_entry_takes_good_bins_alike(bins):
    real, sim = frames()
    assert irf.ScoringConfig(bins=bins).bins == bins_value(bins)
    assert type(bins_value(bins)) in (int, str)
    st = irf.pair_stats(real, sim, bins=bins, need=("nmi",))
    assert st.bins == bins_value(bins)
    assert irf.evaluate(real, sim, bins=bins, weights="nmi=1").metrics["nmi"] == pytest.approx(st.nmi().value)


def test_the_cli_takes_the_libraries_message_for_bins(capsys):
    real, sim = frames()
    rc, err = cli(capsys, "score", "r.npy", "s.npy", "--bins", "0")
    assert rc == 2
    assert "argument --bins: expected an integer in 1..1048576 or 'levels'; got 0" in err
    rc, err = cli(capsys, "score", "r.npy", "s.npy", "--bins", "many")
    assert rc == 2 and "argument --bins: expected an integer in 1..1048576 or 'levels'; got 'many'" in err


def test_the_bins_limit_is_the_cores():
    assert _core.MAX_HIST_BINS == 1 << 20
    real, sim = frames()
    assert irf.pair_stats(real, sim, bins=_core.MAX_HIST_BINS, need=("nmi",)).bins == _core.MAX_HIST_BINS


def test_the_kernel_keeps_only_an_internal_invariant_for_bins():
    """What only the Python layer can send wrong is an internal error, never a second rule."""
    real, sim = frames()
    with pytest.raises(FidelityError, match="^internal: 0 histogram bins"):
        _core.pair_stats(real, sim, PairRequest(bins=0))
    with pytest.raises(FidelityError, match="^internal: one bin per level"):
        _core.pair_stats(real.astype(np.float32), sim.astype(np.float32), PairRequest(levels=True))


# --------------------------------------------------------------------------- shapes
SHAPE_MESSAGE = "real and sim frames differ in shape: (40, 48) vs (40, 50)"


def _sequence(real, sim, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return irf.score_sequence([real, real], [sim, sim], progress=False, **options)


SHAPE_CALLS = {
    "register": lambda r, s: irf.register(r, s),
    "evaluate registered": lambda r, s: irf.evaluate(r, s, register="translation"),
    "evaluate": lambda r, s: irf.evaluate(r, s),
    "pair_stats": lambda r, s: irf.pair_stats(r, s),
    "score_registered": lambda r, s: score_registered(r, s, PairRequest(), model="translation", method="phase"),
    "ssim_map": lambda r, s: irf.maps.ssim_map(r, s),
    "score_sequence registered": lambda r, s: _sequence(r, s, register="translation"),
}


@pytest.mark.parametrize("entry", sorted(SHAPE_CALLS))
def test_every_entry_refuses_a_pair_of_two_shapes_with_one_message(entry):
    real, _ = frames()
    _, sim = frames((40, 50))
    with pytest.raises(ShapeError) as caught:
        SHAPE_CALLS[entry](real, sim)
    # a sequence says which pair first: "registering the first readable pair ([0] and [0]): ..."
    assert str(caught.value).endswith(SHAPE_MESSAGE) and (entry.startswith("score_sequence")
                                                          or str(caught.value) == SHAPE_MESSAGE)


def test_a_sequence_of_array_pairs_of_two_shapes_names_the_shapes_in_each_row():
    real, _ = frames()
    _, sim = frames((40, 50))
    rep = _sequence(real, sim)
    errors = [entry["error"] for entry in rep.frames]
    assert errors and all(e is not None and SHAPE_MESSAGE in e for e in errors), errors


def test_the_cli_names_both_files_and_the_shapes(capsys, tmp_path):
    real, _ = frames()
    _, sim = frames((40, 50))
    np.save(tmp_path / "r.npy", real)
    np.save(tmp_path / "s.npy", sim)
    for extra in ([], ["--register", "translation"]):
        rc, err = cli(capsys, "score", str(tmp_path / "r.npy"), str(tmp_path / "s.npy"), "--bits", "12", *extra)
        assert rc == 2, err
        assert len(err.strip().splitlines()) == 1 and SHAPE_MESSAGE in err
        assert "r.npy" in err and "s.npy" in err


@pytest.mark.parametrize("shape", [(40,), (2, 40, 48)])
def test_the_binding_names_the_frame_that_is_not_2d(shape):
    real, sim = frames()
    bad = np.zeros(shape, np.uint16)
    for call in (lambda: _core.register_frames(real, bad, "translation", "phase"),
                 lambda: _core.pair_stats(real, bad, PairRequest())):
        with pytest.raises(ShapeError, match=r"^sim: expected a 2-D frame, got shape \("):
            call()


# --------------------------------------------------------------------------- dtype names
def test_one_list_of_dtype_names():
    assert tuple(d.name for d in FRAME_DTYPES) == _core.SUPPORTED_DTYPES
    listed = ", ".join(_core.SUPPORTED_DTYPES)
    real, sim = (f.astype(np.int32) for f in frames())
    for call in (lambda: irf.pair_stats(real, sim), lambda: _core.register_frames(real, sim, "translation", "phase"),
                 lambda: _core.pair_stats(real, sim, PairRequest())):
        with pytest.raises(ShapeError) as caught:
            call()
        assert listed in str(caught.value)


# --------------------------------------------------------------------------- models and methods
def test_the_registration_messages_list_the_cores_names():
    real, sim = frames((64, 64))
    with pytest.raises(FidelityError) as caught:
        _core.register_frames(real, sim, "affine", "phase")
    assert str(caught.value).startswith("model must be one of ") and 'got "affine"' in str(caught.value)
    assert all(f"'{name}'" in str(caught.value) for name in _core.REGISTRATION_MODELS)
    with pytest.raises(FidelityError) as caught:
        _core.score_registered(real, sim, PairRequest(), search=("translation", "fast", None))
    assert str(caught.value).startswith("method must be one of ") and 'got "fast"' in str(caught.value)
    assert all(f"'{name}'" in str(caught.value) for name in _core.REGISTRATION_METHODS)


# --------------------------------------------------------------------------- the peak, once
@pytest.mark.parametrize("register", [None, "translation"])
def test_evaluate_resolves_the_peak_once(monkeypatch, register):
    calls = []
    resolve = stats_module.peak_and_valid

    def counted(*args):
        calls.append(args)
        return resolve(*args)

    monkeypatch.setattr(stats_module, "peak_and_valid", counted)
    real, sim = frames((64, 64))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        irf.evaluate(real, sim, bits=12, register=register, hist_range="full")
    assert len(calls) == 1, calls


@pytest.mark.parametrize("dtype,bits,peak,want", [
    (np.uint8, None, None, (0.0, 255.0)),
    (np.uint16, 12, None, (0.0, 4095.0)),
    (np.uint16, 12, 100.0, (0.0, 4095.0)),
    (np.uint16, None, 100.0, (0.0, 100.0)),
    (np.int16, None, None, (-32768.0, 32767.0)),
    (np.int16, None, 50.0, (0.0, 50.0)),
    (np.uint32, None, None, (0.0, 4294967295.0)),
    (np.float32, None, 2.0, (0.0, 2.0)),
    (np.float64, None, None, None),
])
def test_the_full_histogram_range_without_resolving_the_peak_again(dtype, bits, peak, want):
    assert full_range(np.dtype(dtype), bits, peak) == want


def test_plain_keyword_options_are_validated_once_per_set(monkeypatch):
    """A loop scoring pair after pair with the same keywords validates them once: resolving
    the same plain options again gives the same (frozen) object without validating, while a
    different type (``True`` is no ``1``), a container or a calibration is resolved anew."""
    from irfidelity import config as config_module
    from irfidelity.config import ScoringConfig

    monkeypatch.setattr(config_module, "_RESOLVED", {})  # none remembered by earlier tests
    first = ScoringConfig.resolve(None, bits=14, register="translation", nonfinite="mask")
    calls = []
    original = ScoringConfig._validated
    monkeypatch.setattr(ScoringConfig, "_validated", lambda self: calls.append(1) or original(self))
    assert ScoringConfig.resolve(None, nonfinite="mask", register="translation", bits=14) is first
    assert calls == []
    ScoringConfig.resolve(None, bits=1)
    with pytest.raises(ConfigError, match="bits: expected an integer 1..32; got True"):
        ScoringConfig.resolve(None, bits=True)
    weights = {"psnr": 1.0}
    assert ScoringConfig.resolve(None, weights=weights) is not ScoringConfig.resolve(None, weights=weights)
    real, sim = frames()
    for _ in range(3):
        irf.evaluate(real, sim, bits=14)
    assert len(calls) == 5  # bits=1, bits=True (refused), weights twice, evaluate's bits=14 once

#!/usr/bin/env python3
"""Fuzz target: the configuration loader (``ScoringConfig.load``) on TOML and JSON bytes.

The first byte chooses the format (even: TOML, odd: JSON); the rest is the file. A finding is
any exception other than :class:`irfidelity.FidelityError`, a hang (``-timeout``) or memory
beyond ``-rss_limit_mb``. A configuration that loads must also save and load back to itself,
as TOML (or, for a string TOML cannot hold, refuse with a FidelityError) and as JSON.

Run (atheris, https://github.com/google/atheris; ``pip install atheris``)::

    python fuzz/python/fuzz_config.py --seeds corpus_config      # write the seed files, once
    python fuzz/python/fuzz_config.py corpus_config -runs=1000000 -max_len=4096 \\
        -rss_limit_mb=2048 -timeout=10
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import tempfile

import atheris

with atheris.instrument_imports(include=["irfidelity", "tomllib"]):
    from irfidelity.config import ScoringConfig
    from irfidelity.errors import FidelityError

# Scratch files in memory where there is /dev/shm; each is removed after the input that wrote it.
_DIR = "/dev/shm" if os.path.isdir("/dev/shm") else tempfile.gettempdir()
_STEM = os.path.join(_DIR, f"irf_fuzz_config_{os.getpid()}")
_INPUT = (f"{_STEM}_in.toml", f"{_STEM}_in.json")
_OUTPUT = (f"{_STEM}_out.toml", f"{_STEM}_out.json")


@contextlib.contextmanager
def _scratch(path: str):
    try:
        yield path
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)


def _round_trips(config: ScoringConfig) -> None:
    for output in _OUTPUT:
        with _scratch(output) as path:
            try:
                config.save(path)
            except FidelityError:
                if path.endswith(".toml"):
                    continue  # a lone surrogate (from a JSON escape) has no TOML form: refused by name
                raise
            again = ScoringConfig.load(path)
        if again != config:
            raise AssertionError(f"{output} does not load back to the configuration saved:\n{config}\n{again}")


def test_one_input(data: bytes) -> None:
    if not data:
        return
    with _scratch(_INPUT[data[0] & 1]) as path:
        with open(path, "wb") as fh:
            fh.write(data[1:])
        try:
            config = ScoringConfig.load(path)
        except FidelityError:
            return
    _round_trips(config)


def _seeds() -> dict[str, bytes]:
    """Valid configurations and near misses, TOML (first byte 0) and JSON (first byte 1)."""
    full = ScoringConfig(bits=14, peak="range", real_edge_channel="G", mtf_options={"points": [0.1, 0.2, 0.4]},
                         sitf_options={"window": [20.0, 60.0], "method": "logistic"}, register="rigid",
                         grades={"grades": ["pass", "fail"], "cuts": {k: [0.5] for k in
                                                                       ("mtf", "sitf", "psnr", "nmi", "ssim", "noise")}})
    texts = {
        "default": ScoringConfig().to_toml(), "full": full.to_toml(),
        "scoring_table": "[scoring]\nbits = 12\npeak = 100.0\n[scoring.weights]\npsnr = 1.0\nmtf = 0.0\n"
                         "sitf = 0.0\nnmi = 0.0\nssim = 0.0\n",
        "grades_list": "[grades]\ncuts = [1, 2]\n", "anchors": "psnr_anchors = [[30.0, 0.9], [30.0001, 0.99]]\n",
        "options": "[mtf_options]\npoints = 5e7\n[sitf_options]\nlo_frac = 0.2\n'odd key' = 1\n",
        "nested": "a = [[[[[[1]]]]]]\nb.c.d.e = 2\n",
    }
    seeds = {f"{name}.toml": b"\x00" + text.encode() for name, text in texts.items()}
    seeds.update({"default.json": b"\x01" + json.dumps(ScoringConfig().to_dict()).encode(),
                  "full.json": b"\x01" + json.dumps(full.to_dict()).encode(),
                  "weights.json": b'\x01{"weights": "psnr=0.5,ssim=0.5", "hist_range": [0, 4095], "bins": "levels"}',
                  "escape.json": b'\x01{"real_channel": "\\ud800", "pair_by": "NAME", "max_delay": 3}'})
    return seeds


def write_seeds(directory: str) -> None:
    os.makedirs(directory, exist_ok=True)
    for name, data in _seeds().items():
        with open(os.path.join(directory, name), "wb") as fh:
            fh.write(data)


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--seeds":
        write_seeds(sys.argv[2])
        return
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()

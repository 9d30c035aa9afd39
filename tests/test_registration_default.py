"""The default registration method is defined once (irfidelity.registration.DEFAULT_METHOD) and
every entry point reads it: irf.register, ScoringConfig, the sequence engine's summary and the
command line, which can also choose another method."""

from __future__ import annotations

import inspect
import json
import pathlib
import subprocess
import sys

import irfidelity as irf
from irfidelity.registration import DEFAULT_METHOD, METHODS

DATA = pathlib.Path(__file__).parent / "data" / "thermal"
REAL, SIM = str(DATA / "cptv_v2_frame000.png"), str(DATA / "cptv_v2_frame001.png")


def cli(*args):
    return subprocess.run([sys.executable, "-m", "irfidelity.cli", *args], capture_output=True, text=True, timeout=120)


def test_the_api_defaults_are_the_one_definition():
    assert DEFAULT_METHOD in METHODS
    assert inspect.signature(irf.register).parameters["method"].default == DEFAULT_METHOD
    assert irf.ScoringConfig().register_method == DEFAULT_METHOD
    assert f'register_method = "{DEFAULT_METHOD}"' in irf.ScoringConfig().to_toml()


def test_the_command_line_uses_the_default_and_chooses_another():
    base = ("score", REAL, SIM, "--bits", "14", "--peak", "range", "--register", "translation", "--json", "-")
    default = cli(*base)
    assert default.returncode == 0, default.stderr
    assert json.loads(default.stdout)["config"]["register_method"] == DEFAULT_METHOD
    other = next(m for m in METHODS if m != DEFAULT_METHOD)
    chosen = cli(*base, "--register-method", other)
    assert chosen.returncode == 0, chosen.stderr
    assert json.loads(chosen.stdout)["config"]["register_method"] == other


def test_an_unknown_method_is_one_line_exit_2():
    done = cli("score", REAL, SIM, "--register", "translation", "--register-method", "ecc")
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "--register-method" in done.stderr and len(done.stderr.strip().splitlines()) == 1

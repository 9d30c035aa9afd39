"""The hand-written type stub `irfidelity/_core.pyi` matches the compiled module."""

from __future__ import annotations

import os
import subprocess
import sys


def test_stubtest_finds_no_difference(tmp_path):
    # mypy (the `test` extra) compares every name, signature and default of the stub with
    # the runtime module
    res = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "irfidelity._core"],
        capture_output=True,
        text=True,
        timeout=300,
        env=dict(os.environ, MYPY_CACHE_DIR=str(tmp_path / "mypy_cache")),
    )
    assert res.returncode == 0 and "Success" in res.stdout, res.stdout + res.stderr

"""A script run in a fresh interpreter, for the tests that feed the core hostile input: a
crash or a Rust panic there fails the test instead of ending the test run."""

from __future__ import annotations

import json
import os
import subprocess
import sys


def run_python(script: str, args: list[str], *, timeout: float, stdin: str | None = None):
    """Run ``script`` with ``args`` (``RAYON_NUM_THREADS=2`` unless set); assert that it exited
    cleanly without a panic — none raised, none printed (a third-party decoder's panic caught
    by irfidelity reaches the user as the FrameError only) — and return the JSON of its last
    line of output."""
    env = dict(os.environ)
    env.setdefault("RAYON_NUM_THREADS", "2")
    proc = subprocess.run(
        [sys.executable, "-c", script, *args],
        input=stdin,
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
    )
    assert proc.returncode == 0, f"child died (status {proc.returncode}): {proc.stderr[-3000:]}"
    assert "PanicException" not in proc.stderr and "panicked" not in proc.stderr, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])

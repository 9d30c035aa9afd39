"""The README's Python example and its `irfidelity demo` run as written, on the data shipped
with the package, and show the recommended settings: neither raises a warning."""

from __future__ import annotations

import pathlib
import re
import subprocess
import sys
import warnings

README = pathlib.Path(__file__).parent.parent / "README.md"


def test_readme_example_runs(tmp_path, monkeypatch, capsys):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)
    example = blocks[0]
    assert "irf.evaluate" in example
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        exec(compile(example, "README.md", "exec"), namespace)
    rep = namespace["rep"]
    assert set(rep.components) == {"mtf", "sitf", "psnr", "nmi", "ssim"} and rep.skipped == {}
    assert 0 < rep.fidelity < 1 and rep.config.peak == "range"
    assert rep.notes == []
    assert "fidelity" in capsys.readouterr().out
    assert (tmp_path / "scoring.toml").exists()


def test_readme_demo_command_prints_no_warning():
    assert "irfidelity demo" in README.read_text(encoding="utf-8")
    done = subprocess.run([sys.executable, "-m", "irfidelity.cli", "demo"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert "fidelity" in done.stdout
    assert "warning" not in (done.stdout + done.stderr).lower()
    assert "PSNR peak the real frame's max − min" in done.stdout


def test_demo_uses_the_recommended_psnr_peak():
    from irfidelity.demo import load_demo_data, run_demo

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rep = run_demo(out=None)
    real = load_demo_data()["frame"]
    assert rep.config.peak == "range" and rep.notes == []
    assert rep.metrics["psnr_peak"] == float(real.max()) - float(real.min())


def test_readme_shows_the_verdict_its_example_prints(capsys):
    """The grade line shown in the README is the one the example prints."""
    text = README.read_text(encoding="utf-8")
    shown = re.search(r"^grade\s+(\w+)\s+(\1: .*)$", text, re.M)
    assert shown is not None
    example = re.findall(r"```python\n(.*?)```", text, re.S)[0].replace('rep.config.save("scoring.toml")', "")
    namespace: dict = {}
    exec(compile(example, "README.md", "exec"), namespace)
    rep = namespace["rep"]
    assert rep.grade == shown.group(1) and rep.verdict["reason"] == shown.group(2)
    capsys.readouterr()

"""The README's Python example runs as written, on the data shipped with the package."""

from __future__ import annotations

import pathlib
import re

README = pathlib.Path(__file__).parent.parent / "README.md"


def test_readme_example_runs(tmp_path, monkeypatch, capsys):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)
    example = blocks[0]
    assert "irf.evaluate" in example
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(example, "README.md", "exec"), namespace)
    rep = namespace["rep"]
    assert set(rep.components) == {"mtf", "sitf", "psnr", "nmi", "ssim"} and rep.skipped == {}
    assert 0 < rep.fidelity < 1 and rep.config.peak == "range"
    assert "fidelity" in capsys.readouterr().out
    assert (tmp_path / "scoring.toml").exists()

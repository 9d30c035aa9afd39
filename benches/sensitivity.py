"""How the grade and the fidelity move as a simulator gets worse in one respect.

Each real scene in tests/data (the Lepton recording, the PTW MWIR recording, the DJI Zenmuse
640×512 frame) goes down ladders of blur σ, noise σ, gain, offset, subpixel shift and dead
pixels; synthetic curves and noise recordings go down ladders of MTF50 scale, SiTF slope and
NETD factor (tests/ladders.py defines every rung). For every rung the grade, the component that
set it and the fidelity are printed, and docs/sensitivity.png shows the grade (and the
fidelity) against the rung.

Usage: ``python benches/sensitivity.py [--figure docs/sensitivity.png]`` (about a minute).
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import warnings

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

import ladders  # noqa: E402

GRADES = ("excellent", "good", "fair", "poor")


def _rows(rungs: list) -> list[tuple]:
    return [(step, rep.grade, rep.fidelity, rep.verdict["decided_by"]) for step, rep in rungs]


def run() -> dict[str, dict[str, list[tuple]]]:
    """``{ladder: {scene: [(step, grade, fidelity, decided_by), ...]}}``."""
    out: dict[str, dict[str, list[tuple]]] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # PeakWarning and unit warnings: the rungs are what matters here
        for scene, real, successor, bits in ladders.scenes():
            for name in ladders.IMAGE:
                out.setdefault(name, {})[scene] = _rows(list(ladders.image_ladder(name, real, successor, bits)))
        for name in ladders.CAMERA:
            out[name] = {"synthetic": _rows(list(ladders.camera_ladder(name)))}
    return out


def print_table(results: dict[str, dict[str, list[tuple]]]) -> None:
    for name, by_scene in results.items():
        unit = (ladders.IMAGE.get(name) or ladders.CAMERA[name])[-2 if name in ladders.IMAGE else 1]
        print(f"\n{name} ({unit})")
        for scene, rows in by_scene.items():
            cells = "  ".join(f"{step:g}: {grade} {fidelity:.3f} [{by}]" for step, grade, fidelity, by in rows)
            print(f"  {scene:<32} {cells}")


def draw(results: dict[str, dict[str, list[tuple]]], path: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 3, figsize=(13, 10), constrained_layout=True)
    for ax, (name, by_scene) in zip(axes.ravel(), results.items()):
        for scene, rows in by_scene.items():
            steps = list(range(len(rows)))
            line, = ax.plot(steps, [3 - GRADES.index(g) for _, g, _, _ in rows], "o-", label=scene)
            ax.plot(steps, [3 * f for _, _, f, _ in rows], ":", color=line.get_color(), alpha=0.7)
        ax.set_xticks(range(len(rows)), [f"{s:g}" for s, _, _, _ in rows], fontsize=8)
        ax.set_yticks(range(4), list(reversed(GRADES)))
        ax.set_ylim(-0.3, 3.3)
        ax.set_title(name)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, loc="lower left")
    fig.suptitle("Grade (solid) and 3 × fidelity (dotted) down each ladder of degradation")
    fig.savefig(path, dpi=80)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--figure", type=pathlib.Path, default=ROOT / "docs" / "sensitivity.png")
    args = ap.parse_args()
    results = run()
    print_table(results)
    draw(results, args.figure)
    print(f"\nfigure: {args.figure}")


if __name__ == "__main__":
    main()

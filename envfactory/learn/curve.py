"""The learning curve: one CSV row per evaluation, and PNGs of success rate against steps or wall-clock time."""

from __future__ import annotations

import csv
from dataclasses import asdict, dataclass, fields
from pathlib import Path


@dataclass(frozen=True)
class Evaluation:
    timesteps: int
    success_rate: float
    mean_return: float
    mean_length: float
    episodes: int
    wall_s: float  # training time since the run began, summed over every resumed part


COLUMNS = [f.name for f in fields(Evaluation)]


class CurveWriter:
    """Appends each evaluation to the CSV as it happens, so a stopped run keeps its curve so far.
    With `resume`, the rows already written stay and new ones follow them."""

    def __init__(self, path: Path, resume: bool = False):
        self.path = path
        if resume and path.is_file():
            self.rows: list[Evaluation] = read_csv(path)
            return
        self.rows = []
        with open(path, "w", newline="") as handle:
            csv.writer(handle).writerow(COLUMNS)

    def add(self, row: Evaluation) -> None:
        self.rows.append(row)
        with open(self.path, "a", newline="") as handle:
            csv.DictWriter(handle, COLUMNS).writerow(asdict(row))


def read_csv(path: Path) -> list[Evaluation]:
    with open(path, newline="") as handle:
        return [
            Evaluation(
                int(r["timesteps"]),
                float(r["success_rate"]),
                float(r["mean_return"]),
                float(r["mean_length"]),
                int(r["episodes"]),
                float(r["wall_s"]),
            )
            for r in csv.DictReader(handle)
        ]


AXES = {"timesteps": ("environment steps", 1.0), "wall_s": ("wall-clock time (min)", 1 / 60)}


def plot(curves: dict[str, list[Evaluation]], path: Path, title: str, x: str = "timesteps") -> None:
    """Success rate per evaluation against `x` (timesteps or wall_s), one line per label (matplotlib, part of the
    [train] extra)."""
    import matplotlib

    matplotlib.use("Agg")  # files only: no display needed
    import matplotlib.pyplot as plt

    label_x, scale = AXES[x]
    figure, axis = plt.subplots(figsize=(6, 4))
    for label, rows in curves.items():
        axis.plot(
            [getattr(r, x) * scale for r in rows],
            [100 * r.success_rate for r in rows],
            marker="o",
            markersize=3,
            label=label,
        )
    axis.set_xlabel(label_x)
    axis.set_ylabel("success rate (%)")
    axis.set_ylim(-2, 102)
    axis.grid(alpha=0.3)
    axis.set_title(title, fontsize=10)
    if len(curves) > 1:
        axis.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)

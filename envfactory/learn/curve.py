"""The learning curve: one CSV row per evaluation, and a PNG of success rate against steps."""

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
    wall_s: float


COLUMNS = [f.name for f in fields(Evaluation)]


class CurveWriter:
    """Appends each evaluation to the CSV as it happens, so a stopped run keeps its curve so far."""

    def __init__(self, path: Path):
        self.path = path
        self.rows: list[Evaluation] = []
        with open(path, "w", newline="") as handle:
            csv.writer(handle).writerow(COLUMNS)

    def add(self, row: Evaluation) -> None:
        self.rows.append(row)
        with open(self.path, "a", newline="") as handle:
            csv.DictWriter(handle, COLUMNS).writerow(asdict(row))


def read_csv(path: Path) -> list[Evaluation]:
    with open(path, newline="") as handle:
        return [Evaluation(int(r["timesteps"]), float(r["success_rate"]), float(r["mean_return"]),
                           float(r["mean_length"]), int(r["episodes"]), float(r["wall_s"]))
                for r in csv.DictReader(handle)]


def plot(curves: dict[str, list[Evaluation]], path: Path, title: str) -> None:
    """Success rate per evaluation, one line per label (matplotlib, part of the [train] extra)."""
    import matplotlib

    matplotlib.use("Agg")  # files only: no display needed
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6, 4))
    for label, rows in curves.items():
        axis.plot([r.timesteps for r in rows], [100 * r.success_rate for r in rows], marker="o", label=label)
    axis.set_xlabel("environment steps")
    axis.set_ylabel("success rate (%)")
    axis.set_ylim(-2, 102)
    axis.grid(alpha=0.3)
    axis.set_title(title, fontsize=10)
    if len(curves) > 1:
        axis.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)

"""`envfactory safety-view` draws every robot: a PNG of the default size that is a real picture (the scene,
the arm tinted by clearance, in the colour the lowest clearance calls for) and a positive lowest clearance."""

from __future__ import annotations

import re

import imageio.v3 as iio
import numpy as np
import pytest
from conftest import ALL_IDS
from typer.testing import CliRunner

from envfactory import factory
from envfactory.cli.app import app

runner = CliRunner()
WIDTH, HEIGHT = 800, 600  # render_clearance's default size
ONE_ID_PER_ROBOT = ["UR5eReacherSim-v0", "VX300SPushSim-v0", "RX200PnPGoalSim-v0", "NED2ReacherGoalReal-v0"]


def _tints(image: np.ndarray) -> dict[str, np.ndarray]:
    """Pixels of each clearance tint (safety_view's NEAR, CLOSE, CLEAR colours under the renderer's shading)."""
    r, g, b = (image[..., channel].astype(int) for channel in range(3))
    return {
        "near": (r > g + 100) & (r > b + 100),
        "close": (r > b + 120) & (g > b + 80),
        "clear": (g > r + 40) & (g > b + 40),
    }


def _render(env_id: str, out) -> float:
    result = runner.invoke(app, ["safety-view", env_id, "--out", str(out)])
    assert result.exit_code == 0, result.output
    found = re.search(r"lowest clearance (-?\d+\.\d+) m", result.output)
    assert found, result.output
    return float(found.group(1))


@pytest.mark.parametrize("env_id", ONE_ID_PER_ROBOT)
def test_safety_view_draws_each_robot(env_id, tmp_path):
    out = tmp_path / "safety.png"
    lowest = _render(env_id, out)
    assert lowest > 0, f"{env_id}: the home pose must be clear of the scene and of the arm itself"
    image = iio.imread(out)
    assert image.shape[:2] == (HEIGHT, WIDTH) and image.shape[2] in (3, 4)
    assert image[..., :3].std() > 20, "a blank or nearly uniform frame"
    margin = factory.blueprint(env_id).spec.env.safety.surface_margin
    expected = "near" if lowest < margin else "close" if lowest < 3 * margin else "clear"
    tinted = _tints(image)[expected].sum()
    assert tinted > 200, f"{env_id}: lowest clearance {lowest} m calls for {expected} links; {tinted} such pixels"


@pytest.mark.slow  # every ID, about 0.3 s each (15 s for 48 IDs here): the four above stand for them by default
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_safety_view_draws_every_id(env_id, tmp_path):
    out = tmp_path / "safety.png"
    assert _render(env_id, out) > 0
    assert iio.imread(out)[..., :3].std() > 20

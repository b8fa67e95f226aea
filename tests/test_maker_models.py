"""Our robots' URDFs against the makers' models (reference data, not in the repository).

For every robot whose maker model is present: forward kinematics agree within 1 mm at random joint values,
link masses and centres of mass agree, and each link's collision primitives contain the maker's mesh of that
link (its whole surface, not only its vertices) with at most SLACK outside, and none at all for the links
whose pairs the generated list measures against margins of their own (down to contact). Skipped with the
reason where the models are absent: set ENVFACTORY_ROBOT_MODELS, or keep them at ../shared/robot-models
beside the repository.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from devkit.oracles.maker_models import (
    ROOT,
    configuration,
    link_mesh_points,
    link_primitives,
    models_folder,
    outside_distance,
)

FK_TOLERANCE = 0.001  # m
ROTATION_TOLERANCE = 0.001  # rad
SLACK = 0.01  # m of a maker's mesh allowed outside our primitives
MASS_TOLERANCE = 0.002  # kg: frame-only links carry 1 g where a maker gives none
SAMPLES = 50
DENSE = 0.001  # m between the points checked on each triangle where no slack is allowed


def _our_robots() -> dict[str, Path]:
    robots = {}
    for path in sorted((ROOT / "robots").glob("*.yaml")):
        if path.name.startswith("_"):  # shared files beside the robots (message templates), not robots
            continue
        spec = yaml.safe_load(path.read_text())
        parts = [part["urdf"] for part in spec["model"]["parts"] if "urdf" in part]
        if len(parts) == 1 and len(spec["model"]["parts"]) == 1:
            robots[spec["name"]] = path.parent / parts[0]
    return robots


def _pairs():
    folder = models_folder()
    if folder is None:
        return [
            pytest.param(
                None,
                None,
                None,
                marks=pytest.mark.skip(
                    reason="the makers' robot models are absent: set ENVFACTORY_ROBOT_MODELS or put them at "
                    "../shared/robot-models beside the repository"
                ),
            )
        ]
    pairs = [
        (name, ours, folder / name / f"{name}.urdf")
        for name, ours in _our_robots().items()
        if (folder / name / f"{name}.urdf").is_file()
    ]
    assert pairs, f"{folder} holds no model of any robot in robots/"
    return [pytest.param(*pair, id=pair[0]) for pair in pairs]


def _frames(model: pin.Model, data: pin.Data, q: np.ndarray, strip: str) -> dict[str, pin.SE3]:
    """Every body frame relative to base_link, by name less `strip`."""
    pin.framesForwardKinematics(model, data, q)
    frames = {f.name.removeprefix(strip): data.oMf[i] for i, f in enumerate(model.frames) if f.type == pin.BODY}
    base = frames["base_link"].inverse()
    return {name: base * placement for name, placement in frames.items()}


def _joint_ranges(model: pin.Model) -> dict[str, tuple[float, float]]:
    return {
        model.names[j]: (
            model.lowerPositionLimit[model.joints[j].idx_q],
            model.upperPositionLimit[model.joints[j].idx_q],
        )
        for j in range(1, model.njoints)
        if model.joints[j].nq == 1
    }


@pytest.mark.parametrize("name, ours, maker", _pairs())
def test_forward_kinematics_match_the_maker(name, ours, maker):
    mine, theirs = pin.buildModelFromUrdf(str(ours)), pin.buildModelFromUrdf(str(maker))
    mine_data, theirs_data = mine.createData(), theirs.createData()
    ranges = _joint_ranges(mine)
    assert set(ranges) >= set(theirs.names[1:]), f"{name}: joints of the maker's model missing in ours"
    rng = np.random.default_rng(0)
    worst, worst_turn = 0.0, 0.0
    for _ in range(SAMPLES):
        values = {joint: rng.uniform(low, high) for joint, (low, high) in ranges.items()}
        a = _frames(mine, mine_data, configuration(mine, values), "")
        b = _frames(theirs, theirs_data, configuration(theirs, values), f"{name}/")
        common = set(a) & set(b)
        assert set(a) - {"universe"} <= common, (
            f"{name}: our links {sorted(set(a) - common)} are not in the maker's model"
        )
        for link in common:
            worst = max(worst, float(np.linalg.norm(a[link].translation - b[link].translation)))
            worst_turn = max(worst_turn, float(np.linalg.norm(pin.log3(a[link].rotation.T @ b[link].rotation))))
    assert worst <= FK_TOLERANCE, f"{name}: a link frame is {worst * 1000:.2f} mm from the maker's"
    assert worst_turn <= ROTATION_TOLERANCE, f"{name}: a link frame is turned {worst_turn:.4f} rad from the maker's"


@pytest.mark.parametrize("name, ours, maker", _pairs())
def test_link_masses_and_centres_match_the_maker(name, ours, maker):
    mine, theirs = pin.buildModelFromUrdf(str(ours)), pin.buildModelFromUrdf(str(maker))
    bodies = {theirs.names[j]: theirs.inertias[j] for j in range(theirs.njoints)}
    for j in range(1, mine.njoints):
        joint = mine.names[j]
        theirs_inertia = bodies[joint]
        assert abs(mine.inertias[j].mass - theirs_inertia.mass) <= MASS_TOLERANCE, (name, joint)
        assert np.linalg.norm(mine.inertias[j].lever - theirs_inertia.lever) <= 0.001, (name, joint)


@pytest.mark.parametrize("name, ours, maker", _pairs())
def test_collision_primitives_enclose_the_maker_meshes(name, ours, maker):
    meshes = link_mesh_points(maker, strip=f"{name}/")
    primitives = link_primitives(ours)
    report = {}
    for link, points in meshes.items():
        shapes = primitives.get(link)
        assert shapes, f"{name}: link {link} has a mesh in the maker's model and no collision shape in ours"
        outside = np.min([outside_distance(points, *shape) for shape in shapes], axis=0)
        report[link] = float(outside.max())
    assert max(report.values()) <= SLACK, f"{name}: mesh outside our primitives, m: {report}"


def _links_with_own_margins(name: str) -> set[str]:
    """The links whose pairs the robot's generated list measures against margins of their own."""
    spec = yaml.safe_load((ROOT / "robots" / f"{name}.yaml").read_text())
    pairs_file = (spec.get("safety") or {}).get("collision_pairs")
    if pairs_file is None:
        return set()
    data = yaml.safe_load((ROOT / "robots" / pairs_file).read_text())
    # shape names are the link's name and the shape's index: <link>_<n>
    return {shape.rsplit("_", 1)[0] for entry in data.get("pair_margins", []) for shape in entry[:2]}


@pytest.mark.parametrize("name, ours, maker", _pairs())
def test_links_with_own_margins_enclose_the_maker_meshes_without_slack(name, ours, maker):
    """A pair measured against a margin of its own, down to contact, has no room for a part of the real link
    outside its shapes: those links' primitives must hold the maker's whole mesh, checked every millimetre
    over each triangle."""
    links = _links_with_own_margins(name)
    if not links:
        pytest.skip(f"{name}: no pair has a margin of its own")
    meshes = link_mesh_points(maker, strip=f"{name}/", spacing=DENSE, links=links)
    primitives = link_primitives(ours)
    report = {
        link: float(np.min([outside_distance(points, *shape) for shape in primitives[link]], axis=0).max())
        for link, points in meshes.items()
    }
    assert set(report) == links, (
        f"{name}: links with own margins and no mesh in the maker's model: {links - set(report)}"
    )
    assert max(report.values()) <= 1e-9, f"{name}: mesh outside our primitives, m: {report}"

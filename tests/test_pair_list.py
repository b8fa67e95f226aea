"""The generated self-collision pair list cannot be edited to weaken the safety check without a word: its
checksum covers its entries, and a list whose entries do not match is refused with its file and line and the
command that writes it again."""

from __future__ import annotations

import shutil

import pytest
import yaml

from envfactory.factory import blueprint
from envfactory.schema.errors import SpecError
from envfactory.schema.folders import builtin_root

SHIPPED = builtin_root() / "robots" / "assets" / "ur5e.collision.yaml"
ID = "UR5eReacherSim-v0"


def _override(path) -> list[str]:
    return [f"robot.safety.collision_pairs={path}"]


def test_an_unedited_copy_is_accepted(tmp_path):
    copy = tmp_path / "ur5e.collision.yaml"
    shutil.copy(SHIPPED, copy)
    assert blueprint(ID, _override(copy)).spec.robot.safety.collision_pairs == str(copy)


def test_a_pair_added_to_skipped_is_refused_with_file_line_and_command(tmp_path):
    copy = tmp_path / "ur5e.collision.yaml"
    text = SHIPPED.read_text()
    # the base and the upper arm can touch (a folded shoulder): a "never in collision" line would stop
    # the check from ever measuring them
    edited = text.replace("skipped:\n", "skipped:\n- [base_link_inertia_0, upper_arm_link_0, never in collision]\n", 1)
    assert edited != text
    copy.write_text(edited)
    with pytest.raises(SpecError) as caught:
        blueprint(ID, _override(copy))
    message = str(caught.value)
    line = next(n for n, row in enumerate(edited.splitlines(), 1) if row.startswith("checksum:"))
    assert f"{copy}:{line}" in message
    assert "envfactory collision-pairs ur5e" in message
    assert "robot.safety.collision_pairs" in message


def test_a_list_without_a_checksum_is_refused(tmp_path):
    copy = tmp_path / "ur5e.collision.yaml"
    data = yaml.safe_load(SHIPPED.read_text())
    data.pop("checksum")
    copy.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(SpecError, match="or it has none"):
        blueprint(ID, _override(copy))


def _without_section(text: str, section: str) -> str:
    """The list with one section's header and rows taken out."""
    lines, kept, inside = text.splitlines(keepends=True), [], False
    for line in lines:
        if line.startswith(f"{section}:"):
            inside = True
            continue
        if inside and line.startswith(("- ", "  ")):
            continue
        inside = False
        kept.append(line)
    return "".join(kept)


@pytest.mark.parametrize(
    "section, written, complaint",
    [
        (
            "pair_margins",
            "pair_margins:\n- [base_link_inertia_0, wrist_3_link_0]\n",
            "is not [shape, shape, margin in m]",
        ),
        ("pair_margins", "pair_margins:\n- [base_link_inertia_0, wrist_3_link_0, wide]\n", "margin in m"),
        ("skipped", "skipped: 5\n", "skipped is not a list of rows [shape, shape, reason]"),
        ("never_near", "never_near:\n- base_link_inertia_0\n", "never_near row 'base_link_inertia_0' is not"),
    ],
)
def test_a_row_of_another_form_is_named_by_its_line(tmp_path, section, written, complaint):
    copy = tmp_path / "ur5e.collision.yaml"
    text = _without_section(SHIPPED.read_text(), section)
    at = text.index("checksum:")
    edited = text[:at] + written + text[at:]
    copy.write_text(edited)
    line = edited[:at].count("\n") + 1 + (0 if written.endswith(": 5\n") else 1)
    with pytest.raises(SpecError) as caught:
        blueprint(ID, _override(copy))
    assert f"{copy}:{line}: " in str(caught.value) and complaint in str(caught.value), str(caught.value)


def test_a_skip_that_claims_structure_the_urdf_does_not_have_is_refused_even_with_its_checksum_redone(tmp_path):
    """The wrist and the base are not adjacent: marked so, the pair would never be measured. The checksum only
    proves the generator wrote the list, so the claim itself is checked against the robot's own model."""
    from envfactory.geometry.collision_pairs import checksum

    data = yaml.safe_load(SHIPPED.read_text())
    data["skipped"].append(["base_link_inertia_0", "wrist_1_link_0", "adjacent"])
    data["checksum"] = checksum(data)
    copy = tmp_path / "ur5e.collision.yaml"
    copy.write_text(yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120))
    with pytest.raises(SpecError) as caught:
        blueprint(ID, _override(copy))
    message = " ".join(str(caught.value).split())
    assert (
        "skips base_link_inertia_0 and wrist_1_link_0 as 'adjacent', which the robot's model finds to be neither"
        in message
    ), message

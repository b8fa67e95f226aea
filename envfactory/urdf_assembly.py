"""Assemble one URDF per robot from the parts its YAML names.

PyBullet and Pinocchio load the same assembled file, so simulation and
kinematics can never disagree about the geometry of the chain.
"""

from __future__ import annotations

import atexit
import hashlib
import re
import shutil
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from envfactory.spec.schema import ModelSpec, UrdfPart

# Some vendor URDFs carry attributes and elements in an undeclared XML
# namespace (`drake:acceleration`, `drake:collision_filter_group`), which
# ElementTree refuses; neither PyBullet nor Pinocchio uses them.
_UNDECLARED_ATTRIBUTE = re.compile(r'\s[A-Za-z_][\w.-]*:[\w.-]+="[^"]*"')
_UNDECLARED_ELEMENT = re.compile(r"<([A-Za-z_][\w.-]*):([\w.-]+)\b[^>]*/>|<([A-Za-z_][\w.-]*):([\w.-]+)\b.*?</\3:\4>", re.S)
_TINY_INERTIAL = {"mass": "0.001", "inertia": "1e-6"}

_cache_dir: Path | None = None
_assembled: dict[str, Path] = {}


def _output_dir() -> Path:
    global _cache_dir
    if _cache_dir is None:
        _cache_dir = Path(tempfile.mkdtemp(prefix="envfactory-urdf-"))
        atexit.register(shutil.rmtree, _cache_dir, True)
    return _cache_dir


def resolve_part_path(part: "UrdfPart", asset_root: Path) -> Path:
    if part.airo_models is not None:
        try:
            import airo_models
        except ImportError as exc:  # pragma: no cover - airo-models is a hard dependency
            raise RuntimeError("airo-models is required for robot parts named 'airo_models'") from exc
        return Path(airo_models.get_urdf_path(part.airo_models))
    path = Path(part.urdf)
    return path if path.is_absolute() else (asset_root / path)


def _load_part(path: Path) -> ET.Element:
    text = path.read_text()
    text = _UNDECLARED_ELEMENT.sub("", text)
    text = _UNDECLARED_ATTRIBUTE.sub("", text)
    root = ET.fromstring(text)
    for mesh in root.iter("mesh"):
        filename = mesh.get("filename", "")
        if filename.startswith("package://") or Path(filename).is_absolute():
            continue
        mesh.set("filename", str((path.parent / filename).resolve()))
    return root


def _rename(root: ET.Element, prefix: str) -> None:
    if not prefix:
        return
    for link in root.findall("link"):
        link.set("name", prefix + link.get("name"))
    for joint in root.findall("joint"):
        joint.set("name", prefix + joint.get("name"))
        for tag in ("parent", "child"):
            element = joint.find(tag)
            element.set("link", prefix + element.get("link"))
        mimic = joint.find("mimic")
        if mimic is not None:
            mimic.set("joint", prefix + mimic.get("joint"))
    # transmissions and gazebo tags are irrelevant here and would dangle
    for tag in ("transmission", "gazebo"):
        for element in root.findall(tag):
            root.remove(element)


def _give_links_inertia(root: ET.Element) -> None:
    # PyBullet gives a link without <inertial> a mass of 1 kg, which would
    # load the wrist with phantom weight.
    for link in root.findall("link"):
        if link.find("inertial") is None:
            inertial = ET.SubElement(link, "inertial")
            ET.SubElement(inertial, "origin", xyz="0 0 0", rpy="0 0 0")
            ET.SubElement(inertial, "mass", value=_TINY_INERTIAL["mass"])
            value = _TINY_INERTIAL["inertia"]
            ET.SubElement(inertial, "inertia", ixx=value, iyy=value, izz=value, ixy="0", ixz="0", iyz="0")


def _fixed_joint(name: str, parent: str, child: str, xyz, rpy) -> ET.Element:
    joint = ET.Element("joint", name=name, type="fixed")
    ET.SubElement(joint, "origin", xyz=" ".join(map(str, xyz)), rpy=" ".join(map(str, rpy)))
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    return joint


def assemble(model: "ModelSpec", asset_root: Path, robot_name: str) -> Path:
    """Write the robot's assembled URDF once per process and return its path."""
    key = hashlib.sha1(f"{robot_name}:{asset_root}:{model.model_dump_json()}".encode()).hexdigest()[:16]
    if key in _assembled:
        return _assembled[key]

    robot = ET.Element("robot", name=robot_name)
    link_names: set[str] = set()
    for index, part in enumerate(model.parts):
        part_root = _load_part(resolve_part_path(part, asset_root))
        _rename(part_root, part.prefix)
        names = {link.get("name") for link in part_root.findall("link")}
        clash = names & link_names
        if clash:
            raise ValueError(f"model.parts[{index}] repeats link names {sorted(clash)}: give the part a prefix")
        if index > 0:
            child = _root_link(part_root)
            robot.append(
                _fixed_joint(f"{part.prefix}mount", part.parent, child, part.xyz, part.rpy)
            )
        for element in part_root:
            robot.append(element)
        link_names |= names

    for frame_name, frame in model.frames.items():
        if frame.parent not in link_names:
            raise ValueError(f"model.frames.{frame_name}.parent: no link named {frame.parent!r}")
        ET.SubElement(robot, "link", name=frame_name)
        robot.append(_fixed_joint(f"{frame_name}_joint", frame.parent, frame_name, frame.xyz, frame.rpy))
    _give_links_inertia(robot)

    path = _output_dir() / f"{robot_name}-{key}.urdf"
    ET.ElementTree(robot).write(path, encoding="unicode")
    _assembled[key] = path
    return path


def _root_link(root: ET.Element) -> str:
    children = {joint.find("child").get("link") for joint in root.findall("joint")}
    roots = [link.get("name") for link in root.findall("link") if link.get("name") not in children]
    if len(roots) != 1:
        raise ValueError(f"a URDF part must have one root link, found {roots}")
    return roots[0]

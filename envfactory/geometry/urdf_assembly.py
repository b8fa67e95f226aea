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

from envfactory.schema.errors import suggest

if TYPE_CHECKING:
    from envfactory.schema.models import ModelSpec, UrdfPart

# Some vendor URDFs carry attributes and elements in an undeclared XML
# namespace (`drake:acceleration`, `drake:collision_filter_group`), which
# ElementTree refuses; neither PyBullet nor Pinocchio uses them.
_UNDECLARED_ATTRIBUTE = re.compile(r'\s[A-Za-z_][\w.-]*:[\w.-]+="[^"]*"')
_UNDECLARED_ELEMENT = re.compile(
    r"<([A-Za-z_][\w.-]*):([\w.-]+)\b[^>]*/>|<([A-Za-z_][\w.-]*):([\w.-]+)\b.*?</\3:\4>", re.S
)
_TINY_INERTIAL = {"mass": "0.001", "inertia": "1e-6"}

_cache_dir: Path | None = None
_assembled: dict[str, Path] = {}


def _output_dir() -> Path:
    global _cache_dir
    if _cache_dir is None:
        _cache_dir = Path(tempfile.mkdtemp(prefix="envfactory-urdf-"))
        atexit.register(shutil.rmtree, _cache_dir, True)
    return _cache_dir


class AssemblyError(ValueError):
    """A robot model that cannot be assembled; `path` is the spec path to blame."""

    def __init__(self, path: str, message: str):
        super().__init__(message)
        self.path = path


# Mesh formats both PyBullet and Pinocchio's geometry loader read.
MESH_FORMATS = (".obj", ".stl", ".dae")


def resolve_part_path(part: "UrdfPart", asset_root: Path, where: str = "robot.model.parts.0") -> Path:
    if part.airo_models is not None:
        import airo_models

        try:
            return Path(airo_models.get_urdf_path(part.airo_models))
        except ValueError as exc:
            raise AssemblyError(
                f"{where}.airo_models", f"airo-models has no robot {part.airo_models!r}: {exc}"
            ) from None
    if part.pybullet_data is not None:
        import pybullet_data

        path = Path(pybullet_data.getDataPath()) / part.pybullet_data
        if not path.is_file():
            raise AssemblyError(f"{where}.pybullet_data", f"the installed pybullet_data has no {part.pybullet_data!r}")
        return path
    path = Path(part.urdf)
    path = path if path.is_absolute() else (asset_root / path)
    if not path.is_file():
        raise AssemblyError(f"{where}.urdf", f"no URDF file at {path}")
    return path


def _resolve_mesh(filename: str, urdf_path: Path, packages: dict[str, str], asset_root: Path, where: str) -> Path:
    """A mesh reference as a file path: relative to its URDF, file://, or package:// through
    the packages the robot YAML declares. An undeclared package that is a folder beside the URDF
    is read from there, as PyBullet reads it (pybullet_data's Panda names `package://meshes/...`)."""
    if filename.startswith("package://"):
        package, _, rest = filename.removeprefix("package://").partition("/")
        if package not in packages and (urdf_path.parent / package).is_dir():
            return (urdf_path.parent / package).resolve() / rest
        if package not in packages:
            declared = ", ".join(sorted(packages)) or "none"
            raise AssemblyError(
                "robot.model.packages",
                f"{where} references {filename!r}: declare its package, e.g. "
                f"'packages: {{{package}: <folder>}}' (declared: {declared})",
            )
        folder = Path(packages[package])
        return (folder if folder.is_absolute() else asset_root / folder).resolve() / rest
    filename = filename.removeprefix("file://")
    path = Path(filename)
    return path if path.is_absolute() else (urdf_path.parent / path).resolve()


def _load_part(path: Path, packages: dict[str, str], asset_root: Path, where: str) -> ET.Element:
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise AssemblyError(where, f"cannot read the URDF {path}: {exc}") from None
    text = _UNDECLARED_ELEMENT.sub("", text)
    text = _UNDECLARED_ATTRIBUTE.sub("", text)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise AssemblyError(where, f"the URDF {path} is not valid XML: {exc}") from None
    if root.tag != "robot":
        raise AssemblyError(where, f"the URDF {path} has <{root.tag}> at its root, not <robot>")
    for element in root.findall("link"):
        if not element.get("name"):
            raise AssemblyError(where, f"the URDF {path} has a <link> without a name")
    for joint in root.findall("joint"):
        ends = [joint.find(tag) for tag in ("parent", "child")]
        if not joint.get("name") or any(end is None or not end.get("link") for end in ends):
            raise AssemblyError(
                where,
                f"the URDF {path} has a joint {joint.get('name')!r} without a name, "
                f"<parent link=...> or <child link=...>",
            )
    for mesh in root.iter("mesh"):
        mesh_path = _resolve_mesh(mesh.get("filename", ""), path, packages, asset_root, f"{where} ({path.name})")
        if mesh_path.suffix.lower() not in MESH_FORMATS:
            raise AssemblyError(
                where,
                f"mesh {mesh_path} in {path.name}: format {mesh_path.suffix or '(none)'} is "
                f"not loadable (valid: {', '.join(MESH_FORMATS)})",
            )
        if not mesh_path.is_file():
            raise AssemblyError(
                where, f"mesh {mesh.get('filename')!r} in {path.name} not found (looked at {mesh_path})"
            )
        mesh.set("filename", str(mesh_path))
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


def _replace_inertials(root: ET.Element, inertials: dict, link_names: set[str]) -> None:
    links = {link.get("name"): link for link in root.findall("link")}
    for name, spec in inertials.items():
        if name not in link_names:
            raise AssemblyError(
                f"robot.model.inertials.{name}", f"no link named {name!r} in the parts{suggest(name, link_names)}"
            )
        link = links[name]
        for old in link.findall("inertial"):
            link.remove(old)
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", xyz=" ".join(map(repr, spec.xyz)), rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=repr(spec.mass))
        names = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
        ET.SubElement(inertial, "inertia", **{key: repr(value) for key, value in zip(names, spec.inertia)})


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
        where = f"robot.model.parts.{index}"
        part_root = _load_part(resolve_part_path(part, asset_root, where), model.packages, asset_root, where)
        _rename(part_root, part.prefix)
        names = {link.get("name") for link in part_root.findall("link")}
        clash = names & link_names
        if clash:
            raise AssemblyError(f"{where}.prefix", f"part repeats link names {sorted(clash)}: give it a prefix")
        if index > 0:
            if part.parent not in link_names:
                raise AssemblyError(
                    f"{where}.parent",
                    f"no link named {part.parent!r} in the parts before it{suggest(part.parent, link_names)}",
                )
            child = _root_link(part_root, where)
            robot.append(_fixed_joint(f"{part.prefix}mount", part.parent, child, part.xyz, part.rpy))
        for element in part_root:
            robot.append(element)
        link_names |= names

    for frame_name, frame in model.frames.items():
        if frame.parent not in link_names:
            raise AssemblyError(
                f"robot.model.frames.{frame_name}.parent",
                f"no link named {frame.parent!r}{suggest(frame.parent, link_names)}",
            )
        if frame_name in link_names:
            raise AssemblyError(f"robot.model.frames.{frame_name}", f"the URDF already has a link {frame_name!r}")
        ET.SubElement(robot, "link", name=frame_name)
        robot.append(_fixed_joint(f"{frame_name}_joint", frame.parent, frame_name, frame.xyz, frame.rpy))
    _replace_inertials(robot, model.inertials, link_names)
    _give_links_inertia(robot)

    path = _output_dir() / f"{robot_name}-{key}.urdf"
    ET.ElementTree(robot).write(path, encoding="unicode")
    _assembled[key] = path
    return path


def _root_link(root: ET.Element, where: str) -> str:
    children = {joint.find("child").get("link") for joint in root.findall("joint")}
    roots = [link.get("name") for link in root.findall("link") if link.get("name") not in children]
    if len(roots) != 1:
        raise AssemblyError(where, f"a URDF part must have one root link, found {roots}")
    return roots[0]


def without_visuals(urdf_path: Path) -> Path:
    """The assembled URDF less its <visual> elements, for a simulator that draws nothing: PyBullet parses every
    visual mesh it is given (12 MB of OBJ on the UR5e), about 40 MB and 0.3 s a load, and they change no contact
    and no mass."""
    urdf_path = Path(urdf_path)
    key = f"no-visuals:{urdf_path}"
    if key not in _assembled:
        root = ET.parse(urdf_path).getroot()
        for link in root.findall("link"):
            for visual in link.findall("visual"):
                link.remove(visual)
        path = _output_dir() / f"{urdf_path.stem}-no-visuals.urdf"
        ET.ElementTree(root).write(path, encoding="unicode")
        _assembled[key] = path
    return _assembled[key]

"""The env pages: envs/index.md (every shipped ID) and envs/<family>.md (one spec file's scene, IDs,
`envfactory describe` parts and kwargs)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from devkit.docs import mdtext as md
from envfactory import factory
from envfactory.compiler import Blueprint
from envfactory.registration import registry
from envfactory.schema.folders import family_files
from envfactory.views.describe import Part, description_parts, env_kind, id_summary, kwarg_paths, value_at

PICTURE_SEED = 0


@dataclass(frozen=True)
class Family:
    """A shipped spec file and the IDs it registers, in the order it declares them."""

    name: str
    path: Path
    ids: tuple[str, ...]

    @property
    def page(self) -> str:
        return f"envs/{self.name}.md"

    @property
    def picture(self) -> str:
        return f"img/envs/{self.name}.png"

    @property
    def picture_id(self) -> str:
        """The ID the scene is rendered with: the first simulated standard ID, else the first simulated one."""
        simulated = [i for i in self.ids if registry.record(i).backend == "sim"]
        if not simulated:
            raise ValueError(f"{self.path}: no simulated ID to render the scene with")
        return next((i for i in simulated if not registry.record(i).goal_env), simulated[0])


def shipped_families() -> list[Family]:
    """The built-in spec files with their IDs (IDs of user spec folders stay out of the docs)."""
    by_file: dict[Path, list[str]] = {}
    for env_id, record in registry.records().items():
        if record.source == registry.BUILTIN_SOURCE:
            by_file.setdefault(record.family.path.resolve(), []).append(env_id)
    families = []
    for path in family_files(registry.builtin_root()):
        ids = by_file.get(path.resolve())
        if ids:
            families.append(Family(path.stem, path, tuple(ids)))
    return families


def index_page(families: list[Family]) -> str:
    rows = []
    for family in families:
        for env_id in sorted(family.ids):
            robot, task, backend, obs, action = id_summary(factory.blueprint(env_id))
            rows.append(
                (
                    md.code(env_id),
                    robot,
                    task,
                    backend,
                    obs,
                    action,
                    f"[{family.name}]({family.name}.md#{md.anchor(env_id)})",
                )
            )
    rows.sort()
    intro = (
        "Every ID the shipped spec files register, as `envfactory list` shows them (which also lists the IDs "
        "of your own spec folders). *Obs* is the observation vector's size; goal envs observe a Dict whose "
        "`achieved_goal` and `desired_goal` add 3 each. *Action* is the action vector's size. Sim IDs run on "
        'PyBullet (or MuJoCo with `engine="mujoco"`); Real IDs drive a robot over rosbridge.'
    )
    families_list = "\n".join(
        f"- [{family.name}]({family.name}.md): {_label(family)}, {len(family.ids)} IDs" for family in families
    )
    return md.page(
        "Environments",
        intro,
        md.grid(["ID", "Robot", "Task", "Backend", "Obs", "Action", "Family"], rows),
        "## Families\n\nOne page per spec file: the scene, the IDs, their observation, action and reward "
        "tables, and the kwargs they accept.\n\n" + families_list,
    )


def _label(family: Family) -> str:
    spec = factory.blueprint(family.ids[0]).spec
    return f"{spec.robot.label}, {spec.task.label}"


def family_page(family: Family) -> str:
    blueprints = {env_id: factory.blueprint(env_id) for env_id in family.ids}
    first = family.ids[0]
    spec_file = family.path.relative_to(registry.builtin_root())
    picture = (
        f"![{family.picture_id} after reset(seed={PICTURE_SEED})](../{family.picture})\n\n"
        f"*{md.code(family.picture_id)} after `env.reset(seed={PICTURE_SEED})`, drawn by "
        f'`env.render()` with `render_mode="rgb_array"`.*'
    )
    intro = (
        f"{_label(family)}. Declared in {md.code(str(spec_file))}; `envfactory describe ID` prints each "
        f"description below."
    )
    how = (
        f"The first ID in full; for the others, only the parts that differ from {_link(first)}. The kwargs "
        f"each ID takes, with their values, are [below](#kwargs)."
    )
    sections = [intro, picture, "## IDs", _ids_table(blueprints), "## Descriptions", how]
    reference = description_parts(blueprints[first])
    for env_id, compiled in blueprints.items():
        sections.append(f"### {env_id}")
        parts = description_parts(compiled)
        sections += [md.part(p) for p in _shown(parts, None if env_id == first else reference)]
    sections += ["## Kwargs", _kwargs_table(blueprints)]
    return md.page(f"{_label(family)} — {family.name}", *sections)


def _link(env_id: str) -> str:
    return f"[{env_id}](#{md.anchor(env_id)})"


def _ids_table(blueprints: dict[str, Blueprint]) -> str:
    rows = []
    for env_id, compiled in blueprints.items():
        record = registry.record(env_id)
        _, _, backend, obs, action = id_summary(compiled)
        registered = ", ".join(f"{name}={value!r}" for name, value in record.kwargs)
        rows.append(
            (
                _link(env_id),
                backend,
                env_kind(compiled),
                obs,
                action,
                str(compiled.max_episode_steps),
                md.code(registered) if registered else "—",
            )
        )
    return md.grid(["ID", "Backend", "Kind", "Obs", "Action", "Max steps", "Registered with"], rows)


def _shown(parts: list[Part], reference: list[Part] | None) -> list[Part]:
    """The parts of a description to show: all of them, or those that differ from the reference's part of
    the same kind and place. The kwargs line is left to the kwargs table."""
    parts = [p for p in parts if p.kind != "kwargs"]
    if reference is None:
        return parts
    seen: dict[str, int] = {}
    theirs = {}
    for p in reference:
        theirs[(p.kind, seen.setdefault(p.kind, 0))] = md.part(p)
        seen[p.kind] += 1
    shown, seen = [], {}
    for p in parts:
        key = (p.kind, seen.setdefault(p.kind, 0))
        seen[p.kind] += 1
        if p.kind == "summary" or theirs.get(key) != md.part(p):
            shown.append(p)
    return shown


def _kwargs_table(blueprints: dict[str, Blueprint]) -> str:
    paths: dict[str, str] = {}
    for compiled in blueprints.values():
        paths.update(kwarg_paths(compiled.spec))
    rows = []
    for name, path in sorted(paths.items()):
        by_value: dict[str, list[str]] = {}  # the value's repr -> the IDs that have it
        for env_id, compiled in blueprints.items():
            value = repr(value_at(compiled.spec, path)) if name in kwarg_paths(compiled.spec) else None
            by_value.setdefault(value, []).append(env_id)
        rows.append([f"[{name}](../reference/kwargs.md#{md.kwarg_anchor(name)})", md.code(path), _values(by_value)])
    return (
        "Every gym.make kwarg the IDs take, with its value in each (registered kwargs included); "
        "`gym.make(ID, name=value)`, or `-k name=value` on the command line, sets it.\n\n"
        + md.grid(["Kwarg", "Spec path", "Value"], rows)
    )


def _values(by_value: dict[str | None, list[str]]) -> str:
    """`v` when every ID has it; else the exceptions by ID, then the value most IDs have."""

    def shown(value: str | None) -> str:
        return "not accepted" if value is None else md.code(value)

    common = max(by_value, key=lambda value: len(by_value[value]))
    if len(by_value) == 1:
        return shown(common)
    exceptions = "; ".join(f"{shown(value)} in {', '.join(ids)}" for value, ids in by_value.items() if value != common)
    return f"{exceptions}; {shown(common)} in the others"

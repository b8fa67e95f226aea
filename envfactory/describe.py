"""Print a blueprint the way the seed pages lay out an env: index tables first."""

from __future__ import annotations

from rich import box
from rich.console import Console
from rich.table import Table

from envfactory.compiler import Blueprint
from envfactory.managers import ObservationManager


def _table(title: str, *columns: str) -> Table:
    return Table(*columns, title=title, box=box.SIMPLE_HEAD, title_justify="left", show_edge=False)


def observation_table(compiled: Blueprint) -> Table:
    manager = ObservationManager(compiled.policy_observation)
    name = "observation (Box)" if compiled.goal_env else "Observation"
    table = _table(f"{name}: Box({manager.size},)", "Idx", "Dim", "Component", "Source", "Unit")
    for row in manager.table():
        table.add_row(*row)
    return table


def goal_table(compiled: Blueprint) -> Table:
    goal = compiled.spec.task.goal
    table = _table("desired_goal: Box(3,)", "Idx", "Dim", "Component", "Min", "Max")
    for index, axis in enumerate("xyz"):
        table.add_row(str(index), "1", f"goal {axis}", f"{goal.box[0][index]:.3f}", f"{goal.box[1][index]:.3f}")
    return table


def action_table(compiled: Blueprint) -> Table:
    layout = compiled.action
    mode = "EE" if layout.ee else "Joint"
    detail = f"delta × {layout.delta_coeff:g}" if layout.delta else "absolute"
    table = _table(f"Action: Box({layout.size},) — {mode} mode, {detail}", "Num", "Action", "Min", "Max", "Joint",
                   "Unit")
    for index, row in enumerate(layout.rows):
        table.add_row(str(index), row.label, f"{row.low:+.2f}", f"{row.high:+.2f}", row.joint, row.unit)
    return table


def reward_table(compiled: Blueprint) -> Table:
    spec = compiled.spec
    table = _table(f"Reward ({spec.env.reward_type}), tolerance {spec.task.goal.tolerance:g} m", "Name", "Term",
                   "Weight", "Meaning")
    for term in compiled.rewards:
        table.add_row(term.name, term.term.name, f"{term.weight:g}", term.term.description)
    return table


def render_description(compiled: Blueprint, console: Console) -> None:
    spec = compiled.spec
    kind = "goal-conditioned (Dict)" if compiled.goal_env else "standard (Box)"
    console.print(f"[bold]{compiled.env_id}[/] — {spec.robot.label}, {spec.task.label}, {kind}, "
                  f"backend {compiled.backend}, frame {spec.robot.task_frame}, "
                  f"max_episode_steps {compiled.max_episode_steps}")
    console.print(observation_table(compiled))
    if compiled.goal_env:
        console.print(goal_table(compiled))
        source = "EE" if compiled.achieved_from == "ee" else compiled.achieved_from
        console.print(f"achieved_goal: Box(3,) — current {source} XYZ, same frame as desired_goal\n")
    else:
        goal = spec.task.goal
        console.print(f"Goal box: min {list(goal.box[0])}, max {list(goal.box[1])}\n")
    console.print(action_table(compiled))
    console.print(reward_table(compiled))
    active = [f"{t.name} ({t.term.name})" for t in compiled.terminations if t.active]
    console.print(f"Termination: {', '.join(active) or 'none on this reward type'}; "
                  f"truncation at {compiled.max_episode_steps} steps")

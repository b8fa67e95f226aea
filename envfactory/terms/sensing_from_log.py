"""A sensing spec from what the real path measured: `envfactory run --timing-log` records each step's
info["timing"] on a Real ID (the joint reading's age, whether it repeated the last one, the command latency),
and this turns such a log into `task.randomization.sensing` terms, in whole steps of the env's cycle.

A latency is timed from the first command that asks for motion to the first reading that shows it; a command
sent while the arm still moves from the one before may be credited with that motion and read short, so the
terms use medians."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from envfactory.schema.numbers import is_number

JOINT_OBSERVATIONS = ["joint_positions", "joint_velocities"]  # the observation terms that read /joint_states


def read_log(path: Path) -> list[dict[str, float]]:
    """The timing records of a log (one JSON object per line); ValueError names a line that is not one."""
    records = []
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}:{number}: not a JSON timing record ({exc.msg})") from None
        if not isinstance(record, dict) or "joint_reading_age_s" not in record:
            raise ValueError(f"{path}:{number}: not a timing record (it lacks joint_reading_age_s)")
        _check_fields(record, f"{path}:{number}")
        records.append(record)
    if not records:
        raise ValueError(f"{path}: no timing records (write them with `envfactory run REAL_ID --timing-log`)")
    return records


def _check_fields(record: dict, where: str) -> None:
    """The fields the terms are drawn from: an age is a finite time, a repeat a share, a latency a time or
    null/NaN (no motion seen to start that step)."""
    age = record["joint_reading_age_s"]
    if not (is_number(age) and math.isfinite(age) and age >= 0):
        raise ValueError(f"{where}: joint_reading_age_s is {age!r}, not a finite time in seconds (>= 0)")
    repeated = record.get("joint_reading_repeated", 0.0)
    if not (is_number(repeated) and 0.0 <= repeated <= 1.0):
        raise ValueError(f"{where}: joint_reading_repeated is {repeated!r}, not 0 or 1")
    latency = record.get("command_latency_s")
    if latency is not None and not (is_number(latency) and (math.isnan(latency) or 0 <= latency < math.inf)):
        raise ValueError(f"{where}: command_latency_s is {latency!r}, not a time in seconds (or null)")


def sensing_terms(records: list[dict[str, float]], cycle_time: float) -> tuple[dict, list[str]]:
    """The sensing terms the measurements call for, and the measurements themselves, line by line."""
    ages = np.array([r["joint_reading_age_s"] for r in records], float)
    repeated = float(np.mean([r.get("joint_reading_repeated", 0.0) for r in records]))
    latencies = np.array(
        [
            r["command_latency_s"]
            for r in records
            if r.get("command_latency_s") is not None and math.isfinite(r["command_latency_s"])
        ]
    )
    facts = [
        f"{len(records)} steps, cycle {cycle_time:g} s",
        f"joint reading age: median {np.median(ages):.3f} s, 90th percentile {np.percentile(ages, 90):.3f} s",
        f"joint reading repeated the step before's: {repeated:.1%} of steps",
    ]
    # both delays are stated even when they round to zero steps: a robot YAML declares what was measured
    terms: dict[str, dict] = {
        "late_observation": {
            "term": "observation_delay",
            "params": {"steps": min(round(float(np.median(ages)) / cycle_time), 10)},
        }
    }
    if latencies.size:
        median = float(np.median(latencies))
        facts.append(f"command latency: median {median:.3f} s over {latencies.size} commands")
        terms["late_action"] = {"term": "action_delay", "params": {"steps": min(round(median / cycle_time), 10)}}
    else:
        facts.append("command latency: no command that asked for motion was seen to start")
    if repeated > 0:
        terms["dropped_readings"] = {
            "term": "repeated_readings",
            "params": {"observations": JOINT_OBSERVATIONS, "probability": round(min(repeated, 0.99), 3)},
        }
    return terms, facts


def sensing_yaml(terms: dict, facts: list[str], source: str) -> str:
    """The terms as a block to paste into a robot YAML (its real path's timing, joined to every task's
    randomization) or under `task.randomization:` in a task or family spec."""
    lines = [f"# measured on the real path ({source}):"] + [f"#   {fact}" for fact in facts]
    lines.append("sensing:")
    for name, term in terms.items():
        params = ", ".join(f"{key}: {json.dumps(value)}" for key, value in term["params"].items())
        lines.append(f"  {name}: {{term: {term['term']}, params: {{{params}}}}}")
    return "\n".join(lines) + "\n"

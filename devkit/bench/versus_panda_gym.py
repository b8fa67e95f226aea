"""envfactory against panda-gym 3.0.7, side by side in one run.

    pip install -e '.[bench]'
    nice -n 15 python -m devkit.bench.versus_panda_gym [--rounds 5] [--steps 1000] [--policy random|scripted|both]
        [--ids ID ...] [--engines pybullet mujoco] [-k name=value ...] [--markdown [PATH]]
    nice -n 15 python -m devkit.bench.versus_panda_gym --vector 2 [--rounds 3] [--steps 300] [--markdown [PATH]]

Every (env, round) runs in a fresh process; the rounds interleave the envs
(round 1 runs every env once, then round 2, ...), each panda-gym env between
the envfactory envs of its task, so a busy spell on the machine hits both
sides of a comparison. The table shows medians over the rounds; the ratio is
the median of the per-round ratios.

Per env: steps/s of env.step (the policy's own time left out), the ratio to
panda-gym's env of the same task in the same run, µs per step inside
PyBullet's stepSimulation and outside it, the time outside it as a share of
panda-gym's own in the same round (µs a step differ up to 1.7× between machines
of one kind; the share holds), substeps per step, simulated
seconds per wall second, reset time, the first 5 steps' time (a process's
first steps load the compiled kernels: kept out of the timed steps),
gym.make / import times and the process's peak memory. Random actions are action_space.sample() at full scale; the
scripted experts are envfactory's own and, for panda-gym, a proportional
controller of the same stages (reach; push from behind; pick and place).
With --engines, each envfactory ID runs on each engine named (a row per
engine); physics time is MuJoCo's rollout and mj_step calls there. "touching %" is the
share of steps that end with the robot within 2 mm of a task object (the cube, the puck, either of Stack's
cubes; each engine's own distance query, outside the timed step): how much of the run is contact.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import sys
import time

from devkit.kwarg_option import add_kwarg_option, kwargs_from
from devkit.processes import emit, run_worker
from devkit.report import Report, add_markdown_option

WARM_UP_STEPS = 5
# envfactory task (as its IDs spell it: "Reach" is in "UR5eReacherSim-v0" and "PandaReachSim-v0") -> panda-gym ID
PANDA_TWIN = {
    "Reach": "PandaReach-v3",
    "Push": "PandaPush-v3",
    "PnP": "PandaPickAndPlace-v3",
    "Slide": "PandaSlide-v3",
    "Stack": "PandaStack-v3",
}
ENVFACTORY_IDS = [
    "UR5eReacherSim-v0",
    "UR5ePushSim-v0",
    "UR5ePnPSim-v0",
    "VX300SReacherSim-v0",
    "VX300SPushSim-v0",
    "VX300SPnPSim-v0",
]


def is_panda_gym(env_id: str) -> bool:
    return env_id in PANDA_TWIN.values()


def panda_twin(env_id: str) -> str | None:
    for task, twin in PANDA_TWIN.items():
        if task in env_id and not is_panda_gym(env_id):
            return twin
    return None


# ---------------------------------------------------------------- worker (one env, one fresh process)


class PhysicsClock:
    """Times every pybullet.stepSimulation call (and MuJoCo's rollout and mj_step calls). Both packages look
    the function up on the module at call time (envfactory in its advance loop, panda-gym through its
    BulletClient), so one patch measures both alike. `clock`: wall time by default; step_parts.py reads CPU time."""

    def __init__(self, clock=time.perf_counter):
        import pybullet

        self.seconds, self.calls = 0.0, 0
        self._clock = clock
        pybullet.stepSimulation = self._timed(pybullet.stepSimulation, lambda kwargs: 1)
        try:
            import mujoco
            from mujoco import rollout
        except ImportError:
            return
        # the MuJoCo engine plays a cycle's substeps in one rollout call, and steps in place where a cycle only
        # holds still (the backend looks both up at each call)
        rollout.Rollout.rollout = self._timed(rollout.Rollout.rollout, lambda kwargs: kwargs.get("nstep") or 1)
        mujoco.mj_step = self._timed(mujoco.mj_step, lambda kwargs: 1)

    def _timed(self, original, substeps):
        """`original`, adding its time and its substeps (from its keyword arguments) to the clock."""
        clock = self._clock

        def timed(*args, **kwargs):
            start = clock()
            result = original(*args, **kwargs)
            self.seconds += clock() - start
            self.calls += substeps(kwargs)
            return result

        return timed

    def read(self) -> tuple[float, int]:
        return self.seconds, self.calls


class PandaExpert:
    """A proportional controller in panda-gym's EE action space (Δ of 5 cm per unit), staged as
    envfactory's experts are: reach the goal; push the cube from behind; pick, lift and place."""

    GAIN = 10.0

    def __init__(self, env, task: str):
        if task not in ("Reach", "Push", "PnP"):
            raise ValueError(f"no scripted panda-gym controller for {task}: run it with --policy random")
        self.env, self.task = env.unwrapped, task
        self.stage = 0

    def reset(self) -> None:
        self.stage = 0

    def _towards(self, ee, target, gripper=None):
        import numpy as np

        move = np.clip(self.GAIN * (np.asarray(target) - ee), -1.0, 1.0)
        return move if gripper is None else np.append(move, gripper)

    def __call__(self, observation):
        import numpy as np

        ee = observation["observation"][:3]
        goal = observation["desired_goal"]
        if self.task == "Reach":
            return self._towards(ee, goal)
        cube = observation["achieved_goal"]
        if self.task == "Push":
            direction = (goal - cube)[:2]
            direction = direction / max(np.linalg.norm(direction), 1e-6)
            behind = cube + np.append(-0.06 * direction, 0.0)
            if self.stage == 0:
                if np.linalg.norm(ee[:2] - behind[:2]) < 0.01:
                    self.stage = 1
                return self._towards(ee, behind + [0.0, 0.0, 0.03])
            return self._towards(ee, cube + np.append(0.5 * direction * 0.05, 0.0) + (goal - cube) * 0.5)
        # pick and place: over the cube, down, close, carry to the goal
        width = observation["observation"][6]
        if self.stage == 0:
            if np.linalg.norm(ee[:2] - cube[:2]) < 0.005:
                self.stage = 1
            return self._towards(ee, cube + [0.0, 0.0, 0.05], 1.0)
        if self.stage == 1:
            if abs(ee[2] - cube[2]) < 0.005:
                self.stage = 2
            return self._towards(ee, cube, 1.0)
        if self.stage == 2:
            if width < 0.045:
                self.stage = 3
            return self._towards(ee, cube, -1.0)
        return self._towards(ee, goal, -1.0)


def _touching(env, env_id: str):
    """A function telling whether the robot ends a step within 2 mm of any of the task's objects (a cube, a puck,
    both of Stack's cubes), or None without one."""
    unwrapped = env.unwrapped
    if is_panda_gym(env_id):
        sim = unwrapped.sim
        # panda-gym names its task bodies "object", or "object1" and "object2" (Stack)
        objects = [index for name, index in sim._bodies_idx.items() if name.startswith("object")]
        if not objects:
            return None
        robot = sim._bodies_idx["panda"]
        return lambda: any(sim.physics_client.getClosestPoints(robot, body, 0.002) for body in objects)
    backend = unwrapped.backend
    names = list(unwrapped.blueprint.spec.task.objects)
    if not names:
        return None
    if hasattr(backend, "client"):
        import pybullet

        bodies = [backend.objects[name] for name in names]
        return lambda: any(
            pybullet.getClosestPoints(backend.body, body, 0.002, physicsClientId=backend.client) for body in bodies
        )
    import mujoco

    model, data = backend.model, backend.data
    bodies = {backend.handles.object_body[name] for name in names}
    objects = [g for g in range(model.ngeom) if model.geom_bodyid[g] in bodies]
    robot = [g for g in range(model.ngeom) if model.body(model.geom_bodyid[g]).name.startswith("robot/")]
    # mj_geomDistance returns distmax itself for anything farther: ask up to 1 cm, count what is nearer than 2 mm
    return lambda: any(mujoco.mj_geomDistance(model, data, g, o, 0.01, None) < 0.002 for g in robot for o in objects)


def _policy(env, env_id: str, kind: str, seed: int):
    if kind == "random":
        env.action_space.seed(seed)
        sample = env.action_space.sample
        return lambda observation: sample(), lambda: None
    if is_panda_gym(env_id):
        task = next(t for t, twin in PANDA_TWIN.items() if twin == env_id)
        expert = PandaExpert(env, task)
        return expert, expert.reset
    from envfactory.experts import make_policy

    expert = make_policy("scripted", env)
    return expert, expert.reset


def work(env_id: str, steps: int, policy: str, seed: int, kwargs: dict) -> dict:
    start = time.perf_counter()
    if is_panda_gym(env_id):
        import panda_gym  # noqa: F401  (registers the Panda IDs)
    else:
        import envfactory  # noqa: F401
    import_s = time.perf_counter() - start
    import gymnasium as gym
    import numpy as np

    start = time.perf_counter()
    env = gym.make(env_id, **({} if is_panda_gym(env_id) else kwargs))
    make_s = time.perf_counter() - start
    unwrapped = env.unwrapped
    if is_panda_gym(env_id):
        cycle = unwrapped.sim.n_substeps * unwrapped.sim.timestep
    else:
        cycle = unwrapped.blueprint.spec.env.timing.action_cycle_time
    resets = []
    for i in range(20):
        t = time.perf_counter()
        env.reset(seed=seed * 100 + i)
        resets.append(time.perf_counter() - t)

    # The first steps of a process load the compiled kernels (numba's cache) and warm PyBullet's and MuJoCo's
    # caches: a one-time cost, reported on its own ("first steps ms") and kept out of the steady-state steps/s.
    t = time.perf_counter()
    for _ in range(WARM_UP_STEPS):
        env.step(env.action_space.sample())
    first_steps_s = time.perf_counter() - t

    clock = PhysicsClock()
    act, restart = _policy(env, env_id, policy, seed)
    observation, _ = env.reset(seed=seed)
    restart()
    stepping, episodes, successes, touching = 0.0, 0, 0, 0
    touches = _touching(env, env_id)
    physics_before, calls_before = clock.read()
    for _ in range(steps):
        action = act(observation)
        t = time.perf_counter()
        observation, _, terminated, truncated, info = env.step(action)
        stepping += time.perf_counter() - t
        if touches is not None:
            physics_pause = clock.read()
            touching += touches()
            clock.seconds, clock.calls = physics_pause  # a distance query is no physics step
        if terminated or truncated:
            episodes += 1
            successes += bool(info.get("is_success", False))
            observation, _ = env.reset()  # resets are timed apart, above
            restart()
    physics, calls = clock.read()
    physics, calls = physics - physics_before, calls - calls_before
    counts = getattr(unwrapped.backend, "cycle_counts", None) if not is_panda_gym(env_id) else None
    played = None
    if counts is not None:  # how the fast fidelity played the cycles (all runs, resets' included)
        kinds = (counts.kinematic, counts.at_rest, counts.carried, counts.dynamic)
        total = max(1, sum(kinds))
        played = "/".join(f"{100 * n / total:.0f}" for n in kinds)
    env.close()
    per_step = stepping / steps
    return {
        "id": env_id,
        "policy": policy,
        "seed": seed,
        "steps_per_s": 1.0 / per_step,
        "physics_us": 1e6 * physics / steps,
        "outside_us": 1e6 * (stepping - physics) / steps,
        "substeps": calls / steps,
        "sim_s_per_wall_s": cycle / per_step,
        "reset_ms": 1e3 * float(np.median(resets)),
        "first_steps_ms": 1e3 * first_steps_s,
        "make_s": make_s,
        "import_s": import_s,
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "episodes": episodes,
        "successes": successes,
        "played": played,
        "touching": None if touches is None else 100.0 * touching / steps,
    }


def work_vector(env_id: str, steps: int, num_envs: int, seed: int) -> dict:
    """Env steps per second summed over `num_envs` async sub-processes (gym.make_vec), random actions."""
    if is_panda_gym(env_id):
        import panda_gym  # noqa: F401
    else:
        import envfactory  # noqa: F401
    import gymnasium as gym

    envs = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="async")
    try:
        envs.reset(seed=seed)
        envs.action_space.seed(seed)
        for _ in range(5):  # the sub-processes warm up
            envs.step(envs.action_space.sample())
        start = time.perf_counter()
        for _ in range(steps):
            envs.step(envs.action_space.sample())
        seconds = time.perf_counter() - start
    finally:
        envs.close()
    return {"id": env_id, "num_envs": num_envs, "seed": seed, "steps_per_s": steps * num_envs / seconds}


# ---------------------------------------------------------------- orchestration


def run_one(label: str, steps: int, policy: str, seed: int, kwargs: list[str], vector: int = 0) -> dict:
    """One env in a fresh process; `label` is an ID, or an ID and an engine as 'ID [engine]'."""
    env_id, _, engine = label.partition(" [")
    if engine:
        kwargs = [*kwargs, f"engine={engine.rstrip(']')}"]
    command = [
        sys.executable,
        "-m",
        "devkit.bench.versus_panda_gym",
        "--worker",
        env_id,
        "--steps",
        str(steps),
        "--policy",
        policy,
        "--seed",
        str(seed),
        "--vector-worker",
        str(vector),
        *[a for k in kwargs for a in ("-k", k)],
    ]
    return {**run_worker(command, f"{env_id} ({policy})"), "id": label}


COLUMNS = [
    ("steps/s", "steps_per_s", "{:,.0f}"),
    ("÷ panda-gym", "ratio", "{:.2f}×"),
    ("µs outside physics", "outside_us", "{:,.0f}"),
    ("outside ÷ panda-gym's", "outside_ratio", "{:.2f}×"),
    ("physics µs/step", "physics_us", "{:,.0f}"),
    ("substeps/step", "substeps", "{:.1f}"),
    ("sim s / wall s", "sim_s_per_wall_s", "{:,.0f}"),
    ("reset ms", "reset_ms", "{:.2f}"),
    (f"first {WARM_UP_STEPS} steps ms", "first_steps_ms", "{:.1f}"),
    ("make s", "make_s", "{:.2f}"),
    ("import s", "import_s", "{:.2f}"),
    ("peak MB", "peak_mb", "{:.0f}"),
    ("success", "success", "{}"),
    ("touching %", "touching", "{:.0f}"),
    ("cycles kinematic/at rest/carried/dynamic %", "played", "{}"),
]


def cells(row: dict) -> list[str]:
    """A summarised env's row of the results table, in COLUMNS' order after the env."""
    return [row["id"]] + [("—" if row.get(key) is None else fmt.format(row[key])) for _, key, fmt in COLUMNS]


def summarise(results: list[dict], ids: list[str]) -> list[dict]:
    rows = []
    for env_id in ids:
        mine = [r for r in results if r["id"] == env_id]
        row = {"id": env_id}
        for _, key, _ in COLUMNS:
            if mine and isinstance(mine[0].get(key), (int, float)):
                row[key] = statistics.median(r[key] for r in mine)
        if mine and mine[0].get("played"):
            row["played"] = mine[len(mine) // 2]["played"]  # one round's shares (they barely vary)
        episodes = sum(r["episodes"] for r in mine)
        row["success"] = f"{sum(r['successes'] for r in mine)}/{episodes}" if episodes else "—"
        rows.append(row)
    for row in rows:
        twin = panda_twin(row["id"])  # None for panda-gym's own rows: no result has it, so no ratio
        row["ratio"] = same_round_ratio(results, row["id"], twin, "steps_per_s")
        row["outside_ratio"] = same_round_ratio(results, row["id"], twin, "outside_us")
    return rows


def same_round_ratio(results: list[dict], env_id: str, twin_id: str | None, key: str) -> float | None:
    """The median over rounds of env_id's `key` ÷ its twin's: both ran in the same round, back to back, so the
    ratio holds where µs do not (machines of one kind have differed 1.7× in µs a step)."""
    ratios = [
        mine[key] / other[key]
        for mine in results
        if mine["id"] == env_id and mine.get(key)
        for other in results
        if other["id"] == twin_id and other["seed"] == mine["seed"] and other.get(key)
    ]
    return statistics.median(ratios) if ratios else None


def vector_scaling(ids: list[str], args, report: Report) -> None:
    counts = sorted({1, args.vector})
    results = [
        run_one(env_id, args.steps, "random", r, [], vector=n)
        for r in range(args.rounds)
        for env_id in ids
        for n in counts
    ]
    table = report.table(
        ["env", *(f"num_envs={n}" for n in counts), f"scaling {counts[-1]} ÷ 1"],
        title=f"async vector envs, random actions: env steps/s summed over the sub-processes "
        f"(medians of {args.rounds} rounds x {args.steps} vector steps; {os.cpu_count()} cores)",
    )
    for env_id in ids:
        rates = [
            statistics.median(r["steps_per_s"] for r in results if r["id"] == env_id and r["num_envs"] == n)
            for n in counts
        ]
        table.add(env_id, *(f"{rate:,.0f}" for rate in rates), f"{rates[-1] / rates[0]:.2f}×")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--policy", choices=["random", "scripted", "both"], default="random")
    parser.add_argument("--ids", nargs="*", help="envfactory IDs (default: every Sim ID); their panda-gym twins join")
    add_kwarg_option(parser, help="name=value for every envfactory env")
    parser.add_argument("--engines", nargs="*", help="run each envfactory ID on each of these engines (a row each)")
    add_markdown_option(parser)
    parser.add_argument("--json", help="write every round's raw figures here")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--seed", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--vector-worker", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument(
        "--vector",
        type=int,
        default=0,
        metavar="N",
        help="instead: env steps/s of gym.make_vec(ID, num_envs=1 and N, async), random actions",
    )
    args = parser.parse_args()

    if args.worker:
        if args.vector_worker:
            result = work_vector(args.worker, args.steps, args.vector_worker, args.seed)
        else:
            result = work(args.worker, args.steps, args.policy, args.seed, kwargs_from(args.kwarg))
        emit(result)
        return

    report = Report.start(parser, args, __doc__)
    mine = args.ids or ENVFACTORY_IDS
    if args.engines:
        mine = [f"{env_id} [{engine}]" for env_id in mine for engine in args.engines]
    # each panda-gym env runs between the envfactory envs of its task, so a busy spell of the
    # machine lands on a pair that is compared, not on one side of it
    ids = []
    for task, twin in PANDA_TWIN.items():
        group = [i for i in mine if task in i]
        ids += group[:1] + ([twin] if group else []) + group[1:]
    ids += [i for i in mine if i not in ids]
    if args.vector:
        vector_scaling(ids, args, report)
        report.finish()
        return
    policies = ["random", "scripted"] if args.policy == "both" else [args.policy]
    report.note(
        f"load before: {os.getloadavg()[0]:.2f}; {args.rounds} rounds x {args.steps} steps; "
        f"kwargs: {args.kwarg or 'none'}"
    )
    raw = []
    for policy in policies:
        results = []
        for round_index in range(args.rounds):
            for env_id in ids:
                results.append(run_one(env_id, args.steps, policy, round_index, args.kwarg))
                print(
                    f"  round {round_index + 1} {policy:8} {env_id:22} {results[-1]['steps_per_s']:8.0f} steps/s",
                    file=sys.stderr,
                    flush=True,
                )
        raw += results
        table = report.table(
            ["env"] + [c[0] for c in COLUMNS],
            title=f"{policy} actions (medians of {args.rounds} rounds x {args.steps} steps, fresh process each)",
        )
        for row in summarise(results, ids):
            table.add(*cells(row))
    report.note(f"load after: {os.getloadavg()[0]:.2f}")
    if args.json:
        with open(args.json, "w") as out:
            json.dump(raw, out, indent=1)
    report.finish()


if __name__ == "__main__":
    main()

"""Learning from demonstrations: a dataset of `envfactory collect` checked against the run's env, replayed into
the HER buffer episode by episode, and the behaviour-cloning term on the actor (bc.py).

They need the [train] extra (with minari) and are skipped (with the reason) without it. Whether Push then
learns is measured by devkit/bench/learning.py, not here.
"""

import json
import pickle
import shlex

import gymnasium as gym
import numpy as np
import pytest
from typer.testing import CliRunner

from devkit.bench.run_commands import train_commands
from envfactory.cli.app import app
from envfactory.learn import extra
from envfactory.learn.hyperparams import HyperparameterError, load

runner = CliRunner()
pytestmark = pytest.mark.skipif(
    bool(extra.missing({**extra.TRAIN_MODULES, **extra.PLOT_MODULES, **extra.COLLECT_MODULES})),
    reason="the [train] extra is not installed (pip install -e '.[train]')",
)

ENV_ID = "VX300SReacherGoalSim-v0"
# the kwargs `train` makes this ID with (the default and vx300s_reach blocks of specs/train/sac.yaml)
TRAIN_KWARGS = {"ee_action_type": True, "normalize_actions": True, "normalize_observations": True, "delta_coeff": 0.035}
TINY = ("learning_starts=110", "batch_size=32", "buffer_size=3000", "policy_kwargs.net_arch=[32,32]")


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Four expert episodes on the Reach goal env, collected with the kwargs `train` uses."""
    from envfactory.learn.demonstrations import collect

    root = tmp_path_factory.mktemp("datasets")
    result = collect(ENV_ID, 4, dataset_id="test/reach/expert-v0", env_kwargs=TRAIN_KWARGS, data_path=root)
    return result.path.parent  # the dataset's folder (its data/ inside)


def _model(demos=None, cloning=None, seed=0):
    import gymnasium as gym

    from envfactory.learn.models import make_model

    env = gym.make(ENV_ID, **TRAIN_KWARGS)
    hyper = load("sac", ENV_ID, TINY)
    model, _ = make_model(ENV_ID, hyper, env, seed, env.spec.max_episode_steps, cloning)
    return model, env


def test_demonstrations_enter_the_her_buffer_episode_by_episode(dataset):
    from envfactory.learn.demo_replay import fill, open_demonstrations

    demos = open_demonstrations(str(dataset))
    model, env = _model()
    try:
        buffer = model.replay_buffer
        assert fill(buffer, demos, model.policy.scale_action) == demos.transitions == buffer.pos
        start = 0
        for episode in demos.episodes:
            n = len(episode.actions)
            rows = slice(start, start + n)
            # HER knows each episode's bounds: every transition points at its own episode's start and length
            assert np.all(buffer.ep_start[rows, 0] == start) and np.all(buffer.ep_length[rows, 0] == n)
            assert np.array_equal(buffer.observations["observation"][rows, 0], episode.observations["observation"][:-1])
            assert np.array_equal(
                buffer.next_observations["desired_goal"][rows, 0], episode.observations["desired_goal"][1:]
            )
            # in the buffer's [-1, 1] scale: the env's action box already is, up to rounding
            assert np.allclose(buffer.actions[rows, 0], episode.actions, atol=1e-6)
            assert np.array_equal(buffer.rewards[rows, 0], episode.rewards)
            # the expert reaches every goal: the episode ends terminated, not at the time limit
            assert buffer.dones[start + n - 1, 0] and not buffer.dones[start : start + n - 1, 0].any()
            assert not buffer.timeouts[rows, 0].any()
            start += n
        batch = buffer.sample(64)  # relabelled goals drawn from the demonstration episodes
        assert batch.rewards.shape == (64, 1)
        assert set(np.unique(batch.rewards.numpy())) <= {-1.0, 0.0}
    finally:
        env.close()


def test_an_episode_cut_short_ends_as_a_truncation(dataset):
    from envfactory.learn.demo_replay import open_demonstrations, transitions

    demos = open_demonstrations(str(dataset))
    episode = demos.episodes[0]
    n = len(episode.actions) - 2  # drop the last two steps: the episode no longer ends
    episode.actions, episode.rewards = episode.actions[:n], episode.rewards[:n]
    episode.terminations, episode.truncations = episode.terminations[:n], episode.truncations[:n]
    demos.episodes = [episode]
    last = list(transitions(demos, lambda a: a))[-1]
    done, infos = last[4], last[5]
    assert done[0] and infos == [{"TimeLimit.truncated": True}]  # bootstrapped through, not a terminal state


def test_a_dataset_from_other_kwargs_is_refused_before_a_run_folder_exists(tmp_path, dataset):
    out = tmp_path / "run"
    result = runner.invoke(
        app,
        [
            "train",
            ENV_ID,
            "--demos",
            str(dataset),
            "-k",
            "delta_coeff=0.02",
            "--out",
            str(out),
            "--steps",
            "120",
            *[w for item in TINY for w in ("-p", item)],
        ],
    )
    assert result.exit_code == 1
    assert "they differ in delta_coeff" in result.output
    assert "envfactory collect VX300SReacherGoalSim-v0" in result.output and "-k delta_coeff=0.02" in result.output
    assert "Traceback" not in result.output and not out.exists()


def test_an_unknown_dataset_is_named(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    result = runner.invoke(app, ["train", ENV_ID, "--demos", "nobody/nothing-v0", "--out", str(tmp_path / "run")])
    assert result.exit_code == 1
    assert "--demos nobody/nothing-v0: no such dataset" in result.output and "envfactory collect" in result.output
    assert not (tmp_path / "run").exists()


def test_cloning_pulls_the_actor_toward_the_demonstrated_actions(dataset):
    """The same updates with and without the term: only with it does the actor come close to the expert."""
    import torch
    from stable_baselines3.common.logger import Logger

    from envfactory.learn.bc import CloningSettings
    from envfactory.learn.demo_replay import cloning_buffer, fill, open_demonstrations

    demos = open_demonstrations(str(dataset))
    observations = {
        k: torch.as_tensor(np.concatenate([e.observations[k][:-1] for e in demos.episodes]))
        for k in demos.episodes[0].observations
    }
    expert = torch.as_tensor(np.concatenate([e.actions for e in demos.episodes]))

    def distance_after_updates(cloning):
        model, env = _model(cloning=cloning)
        try:
            model.set_logger(Logger(folder=None, output_formats=[]))
            fill(model.replay_buffer, demos, model.policy.scale_action)
            if cloning is not None:
                model.attach_demonstrations(
                    cloning_buffer(demos, model.observation_space, model.action_space, model.policy.scale_action)
                )
            with torch.no_grad():
                before = float(((model.actor(observations, deterministic=True) - expert) ** 2).sum(1).mean())
            model.train(gradient_steps=150, batch_size=32)
            with torch.no_grad():
                after = float(((model.actor(observations, deterministic=True) - expert) ** 2).sum(1).mean())
            return before, after, model.logger.name_to_value.get("train/bc_loss")
        finally:
            env.close()

    before, with_term, bc_loss = distance_after_updates(CloningSettings(bc_weight=5.0, q_filter=False))
    _, without_term, no_loss = distance_after_updates(None)
    assert bc_loss is not None and no_loss is None  # the term ran in the first case only
    assert with_term < 0.25 * before and with_term < 0.5 * without_term, (before, with_term, without_term)


def test_the_q_filter_keeps_only_states_where_the_critic_prefers_the_demonstration(dataset):
    import torch
    from stable_baselines3.common.logger import Logger

    from envfactory.learn.bc import CloningSettings
    from envfactory.learn.demo_replay import cloning_buffer, open_demonstrations

    demos = open_demonstrations(str(dataset))
    model, env = _model(cloning=CloningSettings(bc_weight=1.0, bc_batch_size=64, q_filter=True))
    try:
        model.set_logger(Logger(folder=None, output_formats=[]))
        model.attach_demonstrations(
            cloning_buffer(demos, model.observation_space, model.action_space, model.policy.scale_action)
        )

        def critic_rating(demonstrated: float, own: float):
            def critic(observations, actions):
                value = own if actions.requires_grad else demonstrated  # the actor's actions carry its gradient
                return (torch.full((actions.shape[0], 1), value),)

            return critic

        for demonstrated, own, kept in ((1.0, 0.0, 1.0), (0.0, 1.0, 0.0)):
            model.critic = critic_rating(demonstrated, own)
            model.logger.name_to_value.clear()
            model.logger.name_to_count.clear()
            model.actor.optimizer.zero_grad()
            model._add_cloning_gradient(model.actor.optimizer, (), {})
            assert model.logger.name_to_value["train/bc_kept"] == kept
            gradient = sum(float(p.grad.abs().sum()) for p in model.actor.parameters() if p.grad is not None)
            assert (gradient > 0) == bool(kept)  # filtered out everywhere: the term adds nothing
    finally:
        env.close()


def test_train_with_demos_records_the_dataset_and_resumes_with_it(tmp_path, dataset):
    out = tmp_path / "run"
    common = ["--eval-every", "120", "--eval-episodes", "1", "--no-progress"]
    result = runner.invoke(
        app,
        [
            "train",
            ENV_ID,
            "--demos",
            str(dataset),
            "--steps",
            "120",
            "--out",
            str(out),
            *common,
            *[w for item in TINY for w in ("-p", item)],
            "-p",
            "demos.bc_weight=2.0",
        ],
    )
    assert result.exit_code == 0, result.output
    meta = json.loads((out / "model.json").read_text())
    demos = meta["demos"]
    assert demos["dataset_id"] == "test/reach/expert-v0" and demos["episodes"] == 4 and demos["terminated"] == 4
    assert demos["cloning"] == {"bc_weight": 2.0, "bc_batch_size": 128, "q_filter": True, "clone_episodes": "all"}
    assert demos["cloned_episodes"] == 4
    assert meta["algorithm_kwargs"]["bc_weight"] == 2.0 and "--demos" in meta["command"]
    with open(out / "replay_buffer.pkl", "rb") as handle:
        buffer = pickle.load(handle)
    assert buffer.pos == demos["transitions"] + 120  # the demonstrations first, then the run's own steps

    again = runner.invoke(app, ["train", "--resume", str(out), "--steps", "240", "--no-progress"])
    assert again.exit_code == 0, again.output
    meta = json.loads((out / "model.json").read_text())
    assert [p["status"] for p in meta["parts"]] == ["finished", "finished"] and meta["timesteps"] == 240
    with open(out / "replay_buffer.pkl", "rb") as handle:
        assert pickle.load(handle).pos == demos["transitions"] + 240  # demonstrations not added twice


def test_the_demos_block_is_checked(tmp_path, dataset):
    from envfactory.learn.bc import CloningSettings

    with pytest.raises(HyperparameterError, match=r"unknown name\(s\) bc_wieght; it takes bc_batch_size, bc_weight"):
        CloningSettings.from_hyperparameters(load("sac", ENV_ID, ["demos.bc_wieght=1"]))
    with pytest.raises(HyperparameterError, match="bc_weight=-1 must be a number >= 0"):
        CloningSettings.from_hyperparameters(load("sac", ENV_ID, ["demos.bc_weight=-1"]))
    result = runner.invoke(
        app, ["train", ENV_ID, "--demos", str(dataset), "-p", "demos.q_filter=maybe", "--out", str(tmp_path / "run")]
    )
    assert result.exit_code == 1 and "q_filter='maybe' must be true or false" in result.output
    assert not (tmp_path / "run").exists()


def test_clone_episodes_successful_clones_only_the_episodes_that_reached_the_goal(dataset):
    """The replay buffer gets every episode; the cloning term's buffer only those whose last step terminated."""
    from dataclasses import replace

    from envfactory.learn.bc import CloningSettings
    from envfactory.learn.demo_replay import DemonstrationError, open_demonstrations
    from envfactory.learn.trainer import _attach_demonstrations

    demos = open_demonstrations(str(dataset))
    first = demos.episodes[0]
    missed = replace(first, terminations=np.zeros_like(first.terminations), truncations=np.ones_like(first.truncations))
    mixed = replace(demos, episodes=[missed, *demos.episodes[1:]])
    model, env = _model(cloning=CloningSettings(clone_episodes="successful"))
    try:
        assert _attach_demonstrations(model, mixed, seed_replay=True) == len(demos.episodes) - 1
        assert model.replay_buffer.pos == mixed.transitions  # every episode, the missed one too
        assert model.demo_buffer.size() == mixed.transitions - len(missed.actions)
    finally:
        env.close()
    with pytest.raises(DemonstrationError, match="none of its 1 episodes reached the goal"):
        replace(demos, episodes=[missed]).successful()
    with pytest.raises(HyperparameterError, match="clone_episodes='best' must be one of all, successful"):
        CloningSettings.from_hyperparameters(load("sac", ENV_ID, ["demos.clone_episodes=best"]))


def test_every_demonstration_action_goes_through_the_scaling_it_is_given(dataset):
    """The shipped envs' action boxes are already [-1, 1], where SB3's scaling is the identity: a scaling that
    is not shows that every action is passed through it, once."""
    from envfactory.learn.demo_replay import open_demonstrations, transitions

    demos = open_demonstrations(str(dataset))
    expected = np.concatenate([0.5 * episode.actions for episode in demos.episodes])
    actions = np.concatenate([item[2] for item in transitions(demos, lambda a: 0.5 * a)])
    assert actions.shape == expected.shape and np.array_equal(actions, expected)


class _Boxed(gym.Env):
    """Records the actions it is given; its two action dimensions have different ranges."""

    def __init__(self):
        self.action_space = gym.spaces.Box(np.array([-2.0, 0.0], np.float32), np.array([2.0, 1.0], np.float32))
        self.observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.received = []

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {}

    def step(self, action):
        self.received.append(np.array(action))
        return np.zeros(1, np.float32), 0.0, False, False, {}


def test_action_noise_has_the_asked_spread_per_dimension_stays_in_the_space_and_follows_the_seed():
    from envfactory.learn.demonstrations import ActionNoise

    inner = _Boxed()
    env = ActionNoise(inner, 0.1)
    env.reset(seed=5)
    for _ in range(4000):
        env.step(np.array([0.0, 0.5], np.float32))  # mid-range: no clipping
    added = np.array(inner.received) - [0.0, 0.5]
    # std 0.1 of each half-range: 0.2 and 0.05; the sample std of 4000 draws is within 5% of it
    assert np.allclose(added.std(axis=0), [0.2, 0.05], rtol=0.05)
    assert np.allclose(added.mean(axis=0), 0.0, atol=[0.02, 0.005])

    inner.received.clear()
    env.reset(seed=5)
    for _ in range(3):
        env.step(np.array([0.0, 0.5], np.float32))
    assert np.allclose(np.array(inner.received) - [0.0, 0.5], added[:3])  # the same seed, the same noise
    env.reset(seed=6)
    env.step(np.array([0.0, 0.5], np.float32))
    assert not np.allclose(inner.received[-1] - [0.0, 0.5], added[0])

    inner.received.clear()
    for _ in range(200):
        env.step(np.array([2.0, 1.0], np.float32))  # on the upper bound: half the draws would leave the space
    received = np.array(inner.received)
    assert np.all(received <= [2.0, 1.0]) and np.any(received == [2.0, 1.0], axis=0).all()

    with pytest.raises(ValueError, match="bounded Box"):
        unbounded = _Boxed()
        unbounded.action_space = gym.spaces.Box(-np.inf, np.inf, (2,), np.float32)
        ActionNoise(unbounded, 0.1)


def test_collect_with_action_noise_records_the_executed_actions_and_names_the_noise(tmp_path):
    """The noisy dataset holds other actions than the plain one from the same seeds, each an action the env was
    given (its own action space), and says its noise: in Minari's metadata, to a run reading it, in the CLI."""
    from envfactory.learn.demo_replay import open_demonstrations

    command = ["collect", ENV_ID, "-n", "2", "--data-path", str(tmp_path)] + [
        f"-k{k}={str(v).lower()}" for k, v in TRAIN_KWARGS.items()
    ]
    assert runner.invoke(app, [*command, "--dataset-id", "test/plain-v0"]).exit_code == 0
    noisy_run = runner.invoke(app, [*command, "--dataset-id", "test/noisy-v0", "--action-noise", "0.2"])
    assert noisy_run.exit_code == 0, noisy_run.output
    plain, noisy = (open_demonstrations(str(tmp_path / "test" / n)) for n in ("plain-v0", "noisy-v0"))
    assert plain.action_noise == 0.0 and noisy.action_noise == 0.2
    assert noisy.summary()["action_noise"] == 0.2
    first_plain, first_noisy = plain.episodes[0].actions[0], noisy.episodes[0].actions[0]
    # the same state at reset (same seed), the expert's same first action, plus noise of std 0.2 per dimension
    assert np.all(np.abs(first_noisy) <= 1.0) and 0 < np.abs(first_noisy - first_plain).max() < 1.0
    stored = json.loads((tmp_path / "test" / "noisy-v0" / "data" / "metadata.json").read_text())
    assert "action noise 0.2" in stored["algorithm_name"] and "std 0.2" in stored["description"]

    refused = runner.invoke(app, [*command, "--dataset-id", "test/loud-v0", "--action-noise", "1.5"])
    assert refused.exit_code != 0 and "--action-noise" in refused.output and "Traceback" not in refused.output

    # the learning page's command for a run on the noisy dataset makes the same dataset again
    record = {"env_id": ENV_ID, "env_kwargs": TRAIN_KWARGS, "demos": noisy.summary(), "command": "envfactory train"}
    again = shlex.split(train_commands(record)[0].split("#")[0])
    assert again[:2] == ["envfactory", "collect"] and "--action-noise" in again
    made = runner.invoke(app, [*again[1:], "--data-path", str(tmp_path), "--dataset-id", "test/again-v0"])
    assert made.exit_code == 0, made.output
    remade = open_demonstrations(str(tmp_path / "test" / "again-v0"))
    assert remade.action_noise == 0.2 and len(remade.episodes) == len(noisy.episodes)
    for ours, theirs in zip(remade.episodes, noisy.episodes):
        assert np.array_equal(ours.actions, theirs.actions)


def test_the_collect_command_of_a_run_with_overrides_reads_back_as_the_same_kwargs():
    """The learning page prints how each run's dataset was made; an override list holds brackets and quotes,
    which the shell would eat unless the pair is quoted."""
    from envfactory.cli.common import parse_kwargs

    env_kwargs = {"ee_action_type": True, "delta_coeff": 0.1, "overrides": ["workspace.min=[-0.3, -0.85, 0.827]"]}
    record = {"env_id": ENV_ID, "env_kwargs": env_kwargs, "demos": {"episodes": 3}, "command": "envfactory train"}
    words = shlex.split(train_commands(record)[0].split("#")[0])
    pairs = [words[i + 1] for i, word in enumerate(words) if word == "-k"]
    assert parse_kwargs(pairs) == env_kwargs

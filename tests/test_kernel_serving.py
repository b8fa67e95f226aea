"""The kernels' three forms (geometry/kernels/serving.py): the interpreted twins a cold process serves and the
module built ahead of time (native.py) must answer exactly as numba's compiled kernels do, and warmup.py must
list every argument type an env calls them with, or a warm process would still compile in the foreground (or
find no native entry point of that type)."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import time

import gymnasium as gym
import numba
import numpy as np
import pytest
from conftest import action_modes

import envfactory
from envfactory.geometry.kernels import native, serving, warmup
from envfactory.geometry.kernels.joints import joint_frames
from envfactory.geometry.kernels.serving import kernels

# one ID a family: the Goal twins call the same kernels with the same arrays
SIM_IDS = sorted(i for i, record in envfactory.records().items() if record.backend == "sim" and "GoalSim" not in i)


def _copies(args):
    return [a.copy() if isinstance(a, np.ndarray) else a for a in args]


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b or (a != a and b != b)


def _two_joint_frames(server) -> np.ndarray:
    """A small entry point's answer in the server's form: the frames of a chain of two revolute joints."""
    placement = np.zeros((3, 3, 4))
    placement[:, :, :3] = np.eye(3)
    placement[2, 0, 3] = 0.5
    frames = np.zeros((3, 3, 4))
    tree = (np.array([0, 0, 1]), placement, np.array([0, 1, 1]), np.tile([0.0, 0.0, 1.0], (3, 1)))
    server.joint_frames(np.array([0.3, -0.2]), *tree, np.array([0, 0, 1]), np.ones(3), frames)
    return frames


def _have_compiler() -> bool:
    return shutil.which((sysconfig.get_config_var("CC") or "cc").split()[0]) is not None


@pytest.fixture(scope="session")
def native_kernels():
    """The ahead-of-time module of these sources: built here unless a process (the suite's own background
    warm-up, whose lock this waits for) has built it; None on a machine without a C compiler."""
    folder = serving.cache_folder()
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / serving.LOCK_FILE, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if native.load() is None and _have_compiler():
            warmup.build_native()
        return native.load()


@pytest.fixture
def built_native(native_kernels):
    if native_kernels is None:
        pytest.skip("no C compiler on this machine: no native module to serve")
    return native_kernels


@pytest.fixture
def served_form(monkeypatch, native_kernels):
    """Serves every entry point as: run the interpreted twin (CPython running the kernels' own source: the
    oracle) and the compiled form this machine serves (the native module; numba's just-in-time kernels where
    no C compiler built one) on copies of the same arguments, and record where the compiled answer (return
    values and every array written in place) differs, and the argument types of each call."""
    form, compiled = ("native", native_kernels) if native_kernels else ("compiled", serving.compiled_kernels())
    twins = serving.interpreted_kernels()
    seen: dict[str, set] = {name: set() for name in twins}
    differences: list[str] = []

    def judged(name):
        def call(*args):
            seen[name].add(tuple(numba.typeof(a) for a in args))
            by_twin, by_kernel = _copies(args), _copies(args)
            expected, answer = twins[name](*by_twin), compiled[name](*by_kernel)
            if not _same(answer, expected):
                differences.append(f"{name} {form} returned {answer!r}, interpreted {expected!r}")
            for index, (left, right) in enumerate(zip(by_kernel, by_twin)):
                if not _same(left, right):
                    differences.append(f"{name} {form} argument {index}: {left!r} against {right!r}")
            for target, source in zip(args, by_kernel):
                if isinstance(target, np.ndarray):
                    target[...] = source
            return answer

        return call

    for name in twins:
        monkeypatch.setitem(kernels.__dict__, name, judged(name))
    return seen, differences


@pytest.mark.parametrize("env_id", SIM_IDS)
def test_the_served_kernels_answer_as_their_interpreted_source_at_the_types_warmup_lists(env_id, served_form):
    seen, differences = served_form
    for ee_action_type in action_modes(env_id):
        env = gym.make(env_id, ee_action_type=ee_action_type)
        env.reset(seed=3)
        env.action_space.seed(3)
        for _ in range(25):
            _, _, terminated, truncated, _ = env.step(env.action_space.sample())
            if terminated or truncated:
                env.reset()
        env.close()
    assert differences == []
    assert seen["motion_proof"], "the episodes never reached the proof: the comparison judged nothing"
    declared = {name: {tuple(signature) for signature in signatures} for name, signatures in warmup.SIGNATURES.items()}
    missing = {name: types - declared[name] for name, types in seen.items() if types - declared[name]}
    assert not missing, (
        f"warmup.SIGNATURES lacks these argument types (they would compile in the env's process): {missing}"
    )


def test_a_bad_kernel_mode_is_refused_by_name(monkeypatch):
    monkeypatch.setenv("ENVFACTORY_KERNELS", "fast")
    with pytest.raises(ValueError, match="ENVFACTORY_KERNELS='fast'.*auto, native, compiled, interpreted"):
        serving.KernelServer()


def test_a_cold_process_serves_the_twins_until_the_cache_is_marked_ready(monkeypatch, tmp_path):
    started = []
    monkeypatch.setenv("ENVFACTORY_KERNELS", "auto")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # no native module there
    monkeypatch.setattr(serving, "cache_folder", lambda: tmp_path)
    monkeypatch.setattr(serving, "start_warmup", lambda folder: started.append(folder) or folder / serving.LOG_FILE)
    monkeypatch.setattr(serving, "CHECK_EVERY_S", 0.0)
    server = serving.KernelServer()
    step = _two_joint_frames(server)
    assert server.form == "interpreted" and started == [tmp_path]
    (tmp_path / serving.READY_FILE).write_text(json.dumps(serving.source_stamp()))
    assert np.array_equal(_two_joint_frames(server), step)
    assert server.form == "compiled"
    assert server.joint_frames is serving.compiled_kernels()["joint_frames"]


def test_a_failed_warmup_is_said_and_the_process_compiles_for_itself(monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("ENVFACTORY_KERNELS", "auto")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # no native module there
    monkeypatch.setattr(serving, "cache_folder", lambda: tmp_path)
    monkeypatch.setattr(serving, "start_warmup", lambda folder: folder / serving.LOG_FILE)
    monkeypatch.setattr(serving, "CHECK_EVERY_S", 0.0)
    server = serving.KernelServer()
    _two_joint_frames(server)
    assert server.form == "interpreted"
    (tmp_path / serving.FAILED_FILE).write_text(json.dumps(serving.source_stamp()) + "\nTraceback: ...")
    _two_joint_frames(server)
    assert server.form == "compiled"
    assert "the kernels' warm-up failed" in capsys.readouterr().err


def test_a_cold_process_switches_to_the_native_module_once_it_is_in_place(monkeypatch, tmp_path, built_native):
    built = native.module_path()
    monkeypatch.setenv("ENVFACTORY_KERNELS", "auto")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(serving, "cache_folder", lambda: tmp_path)
    monkeypatch.setattr(serving, "start_warmup", lambda folder: folder / serving.LOG_FILE)
    monkeypatch.setattr(serving, "CHECK_EVERY_S", 0.0)
    server = serving.KernelServer()
    step = _two_joint_frames(server)
    assert server.form == "interpreted"
    native.module_path().parent.mkdir(parents=True)
    shutil.copy2(built, native.module_path())  # what warmup.py's build puts there
    assert np.array_equal(_two_joint_frames(server), step)
    assert server.form == "native"
    assert server.joint_frames is not serving.compiled_kernels()["joint_frames"]


def test_without_a_native_build_the_warmup_fills_numbas_cache_and_says_why(monkeypatch, tmp_path, capsys):
    def no_compiler():
        raise RuntimeError("no C compiler found")

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(serving, "cache_folder", lambda: tmp_path)
    monkeypatch.setattr(warmup, "build_native", no_compiler)
    # one small entry point keeps the compile short; the others take the same path
    monkeypatch.setattr(serving, "compiled_kernels", lambda: {"joint_frames": joint_frames})
    assert warmup.main() == 0
    assert "no C compiler found" in native.failed()
    assert serving.cache_is_ready(tmp_path)
    assert "compiling the safety kernels into" in capsys.readouterr().out


def test_a_process_served_the_native_module_never_imports_numba(built_native):
    probe = (
        "import sys, gymnasium as gym, envfactory\n"
        "from envfactory.geometry.kernels.serving import kernels\n"
        "env = gym.make('VX300SPushSim-v0'); env.reset(seed=0)\n"
        "for _ in range(5): env.step(env.action_space.sample())\n"
        "print(kernels.form, 'numba' in sys.modules, 'llvmlite' in sys.modules)\n"
    )
    environment = {key: value for key, value in os.environ.items() if key != "ENVFACTORY_KERNELS"}
    done = subprocess.run([sys.executable, "-c", probe], env=environment, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[-3:] == ["native", "False", "False"]


def test_native_mode_serves_the_module_and_says_why_when_it_cannot_be_built(monkeypatch, tmp_path, built_native):
    monkeypatch.setenv("ENVFACTORY_KERNELS", "native")
    server = serving.KernelServer()
    _two_joint_frames(server)
    assert server.form == "native"
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # where no module is
    monkeypatch.setattr(serving.subprocess, "run", lambda *args, **kwargs: None)  # a build that leaves nothing
    native.mark_failed("Traceback ...\nCompileError: command 'gcc' failed: No such file or directory")
    with pytest.raises(RuntimeError, match="ENVFACTORY_KERNELS=native: .*command 'gcc' failed"):
        _two_joint_frames(serving.KernelServer())


def test_a_mark_from_other_sources_is_not_taken_for_ready(tmp_path):
    stamp = serving.source_stamp()
    stamp["motion.py"] = [0.0, 1]
    (tmp_path / serving.READY_FILE).write_text(json.dumps(stamp))
    assert not serving.cache_is_ready(tmp_path)
    (tmp_path / serving.READY_FILE).write_text(json.dumps(serving.source_stamp()))
    assert serving.cache_is_ready(tmp_path)


@pytest.mark.slow
def test_from_a_cold_cache_the_first_episodes_run_at_once_and_a_later_process_compiles_nothing(tmp_path):
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "ENVFACTORY_KERNELS": "auto"}
    command = [sys.executable, "-m", "envfactory.cli", "run", "UR5ePushSim-v0", "--episodes", "2", "--policy", "random"]
    started = time.perf_counter()
    first = subprocess.run(command, env=environment, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr
    assert "compiling the safety kernels in the background" in first.stderr
    assert time.perf_counter() - started < 60
    deadline = time.monotonic() + 600
    built = f"{native.MODULE}{sysconfig.get_config_var('EXT_SUFFIX')}"
    while not list(tmp_path.rglob(serving.READY_FILE)) and not list(tmp_path.rglob(built)):
        assert time.monotonic() < deadline, [p.read_text() for p in tmp_path.rglob(serving.LOG_FILE)]
        time.sleep(2)
    probe = (
        "import gymnasium as gym, envfactory\n"
        "from numba.core import event\n"
        "from envfactory.geometry.kernels.serving import kernels\n"
        "count = []\n"
        "class Count(event.Listener):\n"
        "    def on_start(self, ev): count.append(ev)\n"
        "    def on_end(self, ev): pass\n"
        "event.register('numba:compile', Count())\n"
        "for ee in (False, True):\n"
        "    env = gym.make('UR5ePushSim-v0', ee_action_type=ee); env.reset(seed=0)\n"
        "    for _ in range(30): env.step(env.action_space.sample())\n"
        "print(kernels.form, len(count))\n"
    )
    second = subprocess.run([sys.executable, "-c", probe], env=environment, capture_output=True, text=True, timeout=300)
    assert second.returncode == 0, second.stderr
    assert second.stdout.split()[-2:] == ["native" if _have_compiler() else "compiled", "0"]
    assert "compiling the safety kernels" not in second.stderr


def test_numba_switched_off_serves_its_python_functions():
    probe = (
        "import gymnasium as gym, envfactory\n"
        "from envfactory.geometry.kernels.serving import kernels\n"
        "env = gym.make('VX300SPushSim-v0'); env.reset(seed=0)\n"
        "for _ in range(5): env.step(env.action_space.sample())\n"
        "print(kernels.form)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe],
        env={**os.environ, "NUMBA_DISABLE_JIT": "1"},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[-1] == "interpreted"
    assert "compiling the safety kernels" not in done.stderr

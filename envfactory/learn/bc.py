"""Learning from demonstrations: a behaviour-cloning term on the actor, kept where the critic agrees.

Each actor update also pulls the actor's action toward the demonstrated one, on a
batch of demonstration transitions, and only on the states where the critic
rates the demonstrated action above the actor's own (the Q filter): early on
the demonstrations teach, and once the policy does better they stop holding it
back. The training config sets the term (the `demos` block):

    demos: {bc_weight: 1.0, bc_batch_size: 128, q_filter: true, clone_episodes: all}

`clone_episodes: successful` clones only the episodes that reached the goal (ended terminated); the replay
buffer still gets every episode, as HER learns from a miss too. It keeps an expert's misses, refused steps
included, out of the cloned actions. Tried once on UR5e Slide, whose expert misses half its EE-mode episodes: 14%
success at 100k steps, against 26% cloning every episode (one seed each); the shipped settings clone every one.

How it joins the update: SB3's SAC, TD3 and TQC compute the actor loss, zero
the actor's gradients, back-propagate and step the actor's optimizer. A step
pre-hook on that optimizer back-propagates `bc_weight * BC loss` into the same
gradients just before the step, so each update follows actor loss + weighted
BC loss, with SB3's own update loop left as it is.

torch and Stable-Baselines3 are imported inside functions: the CLI imports this
module without the [train] extra.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from envfactory.learn.hyperparams import HyperparameterError, Hyperparameters

CLONED_EPISODES = ("all", "successful")


@dataclass(frozen=True)
class CloningSettings:
    bc_weight: float = 1.0  # 0: the demonstrations only seed the replay buffer
    bc_batch_size: int = 128
    q_filter: bool = True
    clone_episodes: str = "all"  # or "successful": the cloning term's buffer holds only episodes that reached the goal

    @classmethod
    def from_hyperparameters(cls, hyper: Hyperparameters) -> "CloningSettings":
        block = hyper.trainer("demos") or {}
        where = f"the demos block (from {'; '.join(hyper.sources)})"
        if not isinstance(block, dict):
            raise HyperparameterError(f"{where}: must map names to values, e.g. {{bc_weight: 1.0}}")
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(block) - known)
        if unknown:
            raise HyperparameterError(
                f"{where}: unknown name(s) {', '.join(unknown)}; it takes {', '.join(sorted(known))}"
            )
        settings = cls(**block)
        if (
            not isinstance(settings.bc_weight, (int, float))
            or isinstance(settings.bc_weight, bool)
            or settings.bc_weight < 0
        ):
            raise HyperparameterError(f"{where}: bc_weight={settings.bc_weight!r} must be a number >= 0")
        if (
            not isinstance(settings.bc_batch_size, int)
            or isinstance(settings.bc_batch_size, bool)
            or settings.bc_batch_size < 1
        ):
            raise HyperparameterError(f"{where}: bc_batch_size={settings.bc_batch_size!r} must be an integer >= 1")
        if not isinstance(settings.q_filter, bool):
            raise HyperparameterError(f"{where}: q_filter={settings.q_filter!r} must be true or false")
        if settings.clone_episodes not in CLONED_EPISODES:
            raise HyperparameterError(
                f"{where}: clone_episodes={settings.clone_episodes!r} must be one of {', '.join(CLONED_EPISODES)}"
            )
        return settings

    def as_dict(self) -> dict:
        return asdict(self)


def q_value(critic, observations, actions):
    """One value per row: the lowest of the critics (SAC, TD3), or the mean of every quantile (TQC)."""
    import torch

    values = critic(observations, actions)
    if isinstance(values, (tuple, list)):
        return torch.cat(values, dim=1).min(dim=1).values
    return values.reshape(values.shape[0], -1).mean(dim=1)


class CloningTerm:
    """Mixed into SB3's SAC, TD3 or TQC (see `cloning_class`): the BC term's gradient joins each actor update."""

    def __init__(
        self,
        *args,
        bc_weight: float = CloningSettings.bc_weight,
        bc_batch_size: int = CloningSettings.bc_batch_size,
        q_filter: bool = CloningSettings.q_filter,
        clone_episodes: str = CloningSettings.clone_episodes,
        **kwargs,
    ):
        self.bc_weight, self.bc_batch_size, self.q_filter = float(bc_weight), int(bc_batch_size), bool(q_filter)
        self.clone_episodes = str(clone_episodes)
        self.demo_buffer = None
        super().__init__(*args, **kwargs)

    def _setup_model(self) -> None:
        super()._setup_model()
        # SB3's load also builds the model through here, so a loaded model gets the hook too
        self.actor.optimizer.register_step_pre_hook(self._add_cloning_gradient)

    def _excluded_save_params(self) -> list[str]:
        # the demonstrations come from their dataset (model.json names it), not from model.zip
        return [*super()._excluded_save_params(), "demo_buffer"]

    def attach_demonstrations(self, buffer) -> None:
        self.demo_buffer = buffer

    def _add_cloning_gradient(self, optimizer, args, kwargs) -> None:
        if self.demo_buffer is None or self.bc_weight == 0:
            return
        import torch

        batch = self.demo_buffer.sample(self.bc_batch_size, env=self._vec_normalize_env)
        own = self.actor._predict(batch.observations, deterministic=True)
        keep = torch.ones(own.shape[0], device=own.device)
        if self.q_filter:
            with torch.no_grad():
                keep = (
                    q_value(self.critic, batch.observations, batch.actions)
                    > q_value(self.critic, batch.observations, own)
                ).float()
        loss = self.bc_weight * (((own - batch.actions) ** 2).sum(dim=1) * keep).mean()
        loss.backward()
        self.logger.record_mean("train/bc_loss", loss.item())
        self.logger.record_mean("train/bc_kept", keep.mean().item())


_CLASSES: dict[type, type] = {}


def cloning_class(base: type) -> type:
    """`base` (SAC, TD3, TQC) with the cloning term, one class per base."""
    if base not in _CLASSES:
        _CLASSES[base] = type(f"{base.__name__}FromDemonstrations", (CloningTerm, base), {})
    return _CLASSES[base]

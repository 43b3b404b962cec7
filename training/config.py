"""Training configuration: typed defaults in code, YAML overrides (rl-baselines3-zoo style)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drillgym.controllers.plan_schedule import SCHEDULE_SPANS, ScheduleSpec
from drillgym.controllers.residual import check_mode
from drillgym.envs.errors import UserError, read_yaml
from drillgym.training.cell import TrainingCell
from drillgym.training.domain_randomization import check_ranges, training_plan_support
from drillgym.training.schedule_env import ScheduleReward

ALGOS = ("sac", "td3", "ppo")
SCHEDULE_MODE = "schedule"
"""``residual_mode`` of a plan-schedule residual (one tuning of the base per hole, from the plan)."""


@dataclass
class TrainConfig:
    """Everything a residual-training run depends on (units in names; seeds recorded)."""

    algo: str = "sac"
    """SB3 algorithm: sac (default), td3 or ppo."""
    base: str = "li2023"
    """Base controller spec under the residual."""
    residual_scale: float = 0.5
    """Residual ±1 = ± this share of the env's action range (0.5: ±1 mm of correction)."""
    residual_mode: str = "add"
    """``add``: the residual adds ± ``residual_scale`` of the action range; ``gain``: it scales the base's
    lateral correction by ``1 + residual_scale · residual`` (see :data:`drillgym.controllers.residual.RESIDUAL_MODES`);
    ``schedule``: once per hole, from the plan alone, it sets the base's gains and entry schedule
    (``schedule_spans``; :mod:`drillgym.controllers.plan_schedule`), trained one hole per step with a paired
    reward (:mod:`drillgym.training.schedule_env`). The step-level options (``residual_scale``, ``residual_feed``,
    ``residual_axes``, ``observe_*``, ``paired_reward``, the env's reward weights) do not apply to it."""
    schedule_spans: dict[str, float] = field(default_factory=dict)
    """``schedule`` mode: base field -> log2 span of its multiplier (empty: :data:`drillgym.controllers.plan_schedule.SCHEDULE_SPANS`)."""
    schedule_reward: dict[str, float] = field(default_factory=dict)
    """``schedule`` mode: weights of the paired hole reward (:class:`drillgym.training.schedule_env.ScheduleReward`
    fields; empty: its defaults)."""
    residual_feed: bool = False
    """Let the residual change the feed (off: compare at the base's feed, as Li does)."""
    residual_feed_ceiling: str = "base"
    """How fast the feed residual may drill: ``base`` (never faster than the base) or ``nominal`` (it may undo a
    base's slowing, up to the plan's feed; :data:`drillgym.controllers.residual.FEED_CEILINGS`)."""
    residual_axes: str = "lateral"
    """``lateral``: the residual moves the tip across the drill only; ``xyz``: along the base axes too."""
    observe_prev_residual: bool = False
    """Show the policy its own previous residual (``residual_prev``)."""
    observe_plan: bool = False
    """Show the policy the plan's angle, feed, stick-out and cortical thickness (``plan``)."""
    total_timesteps: int = 200_000
    """Agent steps over all environments."""
    n_envs: int = 2
    """Parallel environments (SubprocVecEnv when > 1); a schedule run's holes drilled per step (one batch)."""
    env_workers: int = 1
    """Processes drilling a schedule run's batched holes: this one and ``env_workers - 1`` spawned, each a share of
    the ``n_envs`` slots (the same holes and numbers with any number; :class:`drillgym.training.schedule_vec_env.ScheduleVecEnv`)."""
    seed: int = 0
    """Seed of the policy, the envs and the scenario draws."""
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    """Extra env arguments for training and evaluation (e.g. reward weights: ``reward_force_weight``)."""
    domain_randomization: bool = True
    """Draw a new scenario every episode inside the training ranges."""
    paper_share: float = 0.0
    """Share of the training episodes drilled in the paper scenario (the env's defaults with ``env_kwargs``) instead
    of a draw inside the training ranges (0: every episode drawn)."""
    paired_reward: bool = False
    """Reward each training step relative to the base controller's own episode on the same seed and scenario
    (:class:`drillgym.training.paired_reward.PairedReward`): the same optimum, without the episode-to-episode
    swing of the specimen and scenario. Evaluation and selection are unchanged."""
    cell: str = ""
    """Unmodelled effects of the cell trained for (:class:`drillgym.training.cell.TrainingCell`): an effect spec
    (``"joint_friction:coulomb_rad=4.2e-4"``) or a named cell (``li2023-lab``); '' : the ideal cell. Training,
    evaluation and model selection all run in it."""
    cell_ranges: dict[str, list[float]] = field(default_factory=dict)
    """``{"effect.param": [low, high]}``: each training episode draws that parameter of ``cell`` uniformly in the
    range (evaluation and selection keep ``cell``'s values). ``drillgym train --cell-from-diagnosis`` fills both."""
    dr_ranges: dict[str, list[float]] = field(default_factory=dict)
    """Extra or replaced domain-randomisation ranges, ``{scenario argument: [low, high]}`` on top of
    :data:`drillgym.training.domain_randomization.DR_RANGES` (training and validation draws alike)."""
    net_arch: list[int] = field(default_factory=lambda: [64, 64])
    """Hidden layers of actor and critic."""
    learning_rate: float = 3e-4
    batch_size: int = 256
    buffer_size: int = 200_000
    learning_starts: int = 2_000
    gamma: float = 0.98
    train_freq: int = 1
    gradient_steps: int = 1
    ent_coef: str = "auto_0.01"
    """SAC entropy coefficient: start small so exploration does not swamp the zero-initialised residual."""
    target_entropy: float = -6.0
    """SAC target entropy (more negative than −dim(A) = −3: keep the residual's noise modest)."""
    actor_warmup_steps: int = 0
    """SAC/TD3: agent steps during which only the critic learns (the residual stays at zero)."""
    log_std_init: float = -2.0
    """Initial log standard deviation of the Gaussian policy (SAC/PPO): std 0.14 of the residual range."""
    n_steps: int = 1024
    """PPO rollout length per env."""
    normalize_obs: bool = True
    """VecNormalize on observations (saved with the model)."""
    eval_freq: int = 10_000
    """Agent steps between evaluations (over all envs)."""
    eval_episodes: int = 4
    """Episodes per evaluation."""
    eval_scenarios: str = "paper"
    """``paper``: every evaluation episode in the paper scenario; ``validation``: the paper scenario and
    fixed draws inside the training ranges, one episode each (the best model is picked on these)."""
    checkpoint_freq: int = 20_000
    """Agent steps between checkpoints."""
    selection_paper_episodes: int = 0
    """``model_selection: deviation`` also scores this many paper-scenario episodes (their own seeds, never the
    benchmark's 0..N-1) beside the validation draws: the paper scenario has one episode among the draws."""
    ship_rule: str = "selection_deviation"
    """Which of several training seeds ships (``drillgym train --seeds``), decided on held-in data only, before
    any judging: ``selection_deviation``: the seed whose chosen model has the lowest mean deviation on its own
    selection episodes (``selection.json``), among the seeds whose model beat the base there (all seeds if none
    did); ``none``: name no seed (:mod:`drillgym.eval.learning.ship_rule`)."""
    model_selection: str = "reward"
    """Which saved model becomes ``policy.zip``: ``reward`` (SB3's best mean validation reward) or
    ``deviation`` (the lowest validation deviation among the models that beat the base without a higher peak
    force or +30 % drill time: :mod:`drillgym.training.selection`)."""

    def __post_init__(self) -> None:
        if self.algo not in ALGOS:
            raise UserError(f"algo={self.algo!r}; choose from {ALGOS}")
        if self.selection_paper_episodes < 0:
            raise UserError(f"selection_paper_episodes={self.selection_paper_episodes} must be >= 0")
        if self.model_selection not in ("reward", "deviation"):
            raise UserError(f"model_selection={self.model_selection!r}; choose reward or deviation")
        if self.ship_rule not in ("selection_deviation", "none"):
            raise UserError(f"ship_rule={self.ship_rule!r}; choose selection_deviation or none")
        if self.eval_scenarios not in ("paper", "validation"):
            raise UserError(f"eval_scenarios={self.eval_scenarios!r}; choose paper or validation")

        if self.residual_mode == SCHEDULE_MODE:
            if self.normalize_obs:
                raise UserError(
                    "residual_mode: schedule observes the plan already scaled to [-1, 1]: set normalize_obs: false"
                )
            self.schedule_spec()
            self.schedule_weights()
        else:
            check_mode(self.residual_mode, self.residual_feed_ceiling)
        check_ranges(self.dr_ranges)
        self.training_cell()
        if not 0.0 <= self.paper_share <= 1.0:
            raise UserError(f"paper_share={self.paper_share!r} must be in [0, 1]")
        if self.total_timesteps < 1 or self.n_envs < 1 or self.env_workers < 1:
            raise UserError("total_timesteps, n_envs and env_workers must be >= 1")

    @property
    def schedule(self) -> bool:
        """Whether the residual is a plan schedule (one tuning per hole)."""
        return self.residual_mode == SCHEDULE_MODE

    def schedule_spec(self) -> Any:
        """The :class:`drillgym.controllers.plan_schedule.ScheduleSpec` of a ``schedule`` run.

        Its plan support comes from the training ranges.
        """
        spans = {k: float(v) for k, v in (self.schedule_spans or SCHEDULE_SPANS).items()}
        return ScheduleSpec(self.base, spans, training_plan_support(self.dr_ranges))

    def schedule_weights(self) -> Any:
        """The :class:`drillgym.training.schedule_env.ScheduleReward` of a ``schedule`` run."""
        known = {f.name for f in dataclasses.fields(ScheduleReward)}
        unknown = sorted(set(self.schedule_reward) - known)
        if unknown:
            raise UserError(f"schedule_reward: unknown weight(s) {unknown}; known: {sorted(known)}")
        return ScheduleReward(**{k: float(v) for k, v in self.schedule_reward.items()})

    def training_cell(self) -> TrainingCell:
        """The cell trained for (``cell`` and ``cell_ranges``; checked)."""
        ranges = {}
        for key, bounds in self.cell_ranges.items():
            if not isinstance(bounds, list | tuple) or len(bounds) != 2:
                raise UserError(f"cell_ranges[{key!r}] = {bounds!r}: expected [low, high]")
            ranges[key] = (float(bounds[0]), float(bounds[1]))
        return TrainingCell(self.cell, ranges)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (YAML/JSON-ready)."""
        return dataclasses.asdict(self)


CONFIG_DIR = Path(__file__).resolve().parent / "configs"
"""The training configurations shipped with the package (``--config NAME`` finds ``NAME.yaml`` here)."""


def resolve_config(path: Path | str) -> Path:
    """A YAML path, or the name of a shipped configuration (``smoke``, ``residual_sac``, ...)."""
    p = Path(path)
    if p.exists():
        return p
    named = CONFIG_DIR / f"{p.stem}.yaml"
    if p.parent == Path(".") and named.exists():
        return named
    names = ", ".join(sorted(q.stem for q in CONFIG_DIR.glob("*.yaml")))
    raise UserError(f"training config {str(path)!r} not found (a YAML path, or a shipped config: {names})")


def load_config(path: Path | None, overrides: dict[str, Any] | None = None) -> TrainConfig:
    """Defaults, then the YAML file's keys (a path or a shipped config's name), then ``overrides``.

    Unknown keys raise ``ValueError``.
    """
    data: dict[str, Any] = {}
    if path is not None:
        path = resolve_config(path)
        loaded = read_yaml(Path(path)) or {}
        if not isinstance(loaded, dict):
            raise UserError(f"{path}: expected a mapping of TrainConfig fields, got {type(loaded).__name__}")
        data.update(loaded)
    data.update(overrides or {})
    known = {f.name for f in dataclasses.fields(TrainConfig)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise UserError(f"unknown training option(s) {unknown}; known: {sorted(known)}")
    return TrainConfig(**data)

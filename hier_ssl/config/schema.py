"""Configs are YAML data validated into typed objects; every key is a constructor argument.

This module is data: models that check types and ranges, and nothing from the rest of the package. What
needs a registry (known fields, workers, obstacle behaviours, scenario classes and their defaults) is
checked where the registries live, by ``hier_ssl.envs.parse_config``, the one place configs enter. An
unknown, mistyped or out-of-range key is a ``ConfigError`` whose message names the key's full path (e.g.
``env.frame_skip``). Loading never mutates what the caller passed in.
"""

from __future__ import annotations

import copy
import difflib
import re
import typing
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, Field, ValidationError, model_validator
from pydantic_core import ErrorDetails

from hier_ssl.config.learners import CandidatesConfig, PPOConfig, SACConfig, Strict


class ConfigError(ValueError):
    """A config that cannot be used; the message names the offending key."""


class UnknownSettingError(ConfigError, TypeError):
    """An env constructor's keyword argument that is no key of the task: a ``TypeError``, as Python raises
    for an unexpected keyword argument and clients expect (TorchRL retries without ``frameskip`` on one),
    and still a ``ConfigError``."""


class ObstacleConfig(Strict):
    """One scripted obstacle robot: how it moves (a behaviour of world/obstacles.py) and where it starts."""

    behaviour: str = "public_code"
    options: dict[str, Any] = Field(default_factory=dict)
    # "midpoint": between robot and target (public code); "uniform": anywhere clear of both.
    placement: Literal["midpoint", "uniform"] = "midpoint"


class TaskSettings(Strict):
    """How a manager's decisions become sub-goals, rewards and episode ends (docs/paper.md), shared by the
    paper's environments (``EnvConfig``) and the multi-robot scenarios (``ScenarioConfig``)."""

    action_form: Literal["pose4", "pose6"] = "pose4"
    # "field": the paper's sub-goal in field coordinates; "target": an offset from the target pose, so the
    # zero action is the direct sub-goal (``hier_ssl.manager.actions.decode_subgoal``).
    action_frame: Literal["field", "target"] = "field"
    frame_skip: int = Field(1, ge=1)
    frame_skip_reward: Literal["sum", "last"] = "sum"
    max_steps: int = Field(1200, ge=1)
    success_mode: Literal["add", "replace"] = "add"
    hit_mode: Literal["add", "replace"] = "add"
    # Multiply R_t (+1000) and R_hit (-1000); see ``hier_ssl.manager.rewards.task_reward``.
    success_weight: float = Field(1.0, ge=0, allow_inf_nan=False)
    hit_weight: float = Field(1.0, ge=0, allow_inf_nan=False)
    # R_obst's distance to the nearest obstacle: from the sub-goal (paper text) or the robot (public code).
    obstacle_from: Literal["subgoal", "robot"] = "subgoal"
    # "paper": 13 values + 5 per obstacle in field coordinates (docs/paper.md); "neighbours": 13 + 6 per
    # slot for the ``neighbours`` nearest other robots, relative to the robot
    # (``hier_ssl.manager.neighbours``);
    # "encounters": "neighbours" + 6 closest-approach values per slot (``hier_ssl.manager.encounter``).
    observation: Literal["paper", "neighbours", "encounters"] = "paper"
    neighbours: int = Field(6, ge=0)
    # A spec of hier_ssl.worker.make_worker: "paper", "bangbang", a worker run directory, "+key=value"s.
    worker: str = "paper"
    # The PettingZoo view's agents besides the managers: worker_i and obstacle_j act, one control step a
    # step, in place of the scripted ones.
    expose_worker: bool = False
    expose_obstacles: bool = False
    dt: float = Field(0.025, gt=0)
    substeps: int = Field(2, ge=1)
    # The paper's thresholds (docs/paper.md; hier_ssl.manager.rewards.DIST_THRESHOLD,
    # .success.SPEED_THRESHOLD and .COLLISION_DISTANCE are the same numbers).
    d_th: float = Field(0.05, gt=0)
    theta_th_deg: float = Field(5.0, gt=0)
    speed_th: float = Field(0.05, gt=0)
    collision_distance: float = Field(0.2, gt=0)
    spawn_margin: float = Field(0.1, ge=0)
    field: str = "hardware_challenge"


class EnvConfig(TaskSettings):
    """One learning environment of the paper (docs/paper.md): the Baseline, Proposed or Obstacle task
    (``hier_ssl.envs.tasks``), one controlled robot and the obstacles listed here."""

    task: str = "proposed"
    obstacles: list[ObstacleConfig] = Field(default_factory=list)
    min_start_distance: float = Field(0.2, ge=0)
    # The public code starts the robot 0.2 m from the target with the obstacle at the midpoint, 0.1 m from
    # the robot: such an episode begins inside the collision distance and ends at its first control step
    # as a collision. False refuses that combination; True plays such episodes and counts them.
    allow_start_contact: bool = False

    @property
    def scenario_name(self) -> str:
        """The class that runs this config: the task."""
        return self.task


MAX_AGENTS, MAX_OBSTACLES = 11, 11  # robots a side in an SSL Division A game


class BehaviourConfig(Strict):
    """How every obstacle robot of a scenario moves: a behaviour of ``hier_ssl.world.obstacles``."""

    behaviour: str = "random_walk"
    options: dict[str, Any] = Field(default_factory=dict)


class ScenarioConfig(TaskSettings):
    """One multi-robot scenario over N fields (``hier_ssl.envs.scenarios``). Keys left out take the
    scenario class's ``defaults``, then the values below; ``options`` are the scenario's own settings (its
    ``Options`` model). The task settings mean what they mean in ``EnvConfig``; the task is always
    action-centric ("obstacle" rules, or "proposed" when a field holds a single robot) and the observation
    "neighbours" or "encounters"."""

    scenario: str
    field: str = "division_b"
    num_agents: int = Field(1, ge=1, le=MAX_AGENTS)
    num_obstacles: int = Field(0, ge=0, le=MAX_OBSTACLES)
    obstacles: BehaviourConfig = Field(default_factory=BehaviourConfig)
    options: dict[str, Any] = Field(default_factory=dict)
    frame_skip: int = Field(16, ge=1)
    observation: Literal["neighbours", "encounters"] = "neighbours"

    @property
    def scenario_name(self) -> str:
        """The class that runs this config: the scenario."""
        return self.scenario


TaskConfig = EnvConfig | ScenarioConfig
"""What a core runs: a paper task or a multi-robot scenario (``hier_ssl.envs.make_scenario``)."""


class GoToPointConfig(Strict):
    """The goToPoint task, where the worker is the learner (``hier_ssl.envs.gotopoint``).

    World, thresholds and the episode limit come from the run's ``env`` section (field, dt, substeps,
    d_th, theta_th_deg, speed_th, spawn_margin, max_steps); the reward weights are those of
    ``hier_ssl.worker.rewards``.
    """

    near_fraction: float = Field(0.5, ge=0, le=1)  # share of sub-goals drawn within near_radius of the robot
    near_radius: float = Field(1.0, gt=0)  # m
    moving_fraction: float = Field(0.5, ge=0, le=1)  # share of episodes starting at a random velocity
    angle_weight: float = Field(1.0, ge=0)  # m of distance a heading error of pi rad is worth
    time_cost: float = Field(0.01, ge=0)
    smooth_cost: float = Field(0.01, ge=0)
    success_bonus: float = Field(10.0, ge=0)
    # A training episode ends when the robot is within these of the sub-goal (default: env.d_th and
    # env.theta_th_deg) and slower than env.speed_th. Tighter than the env's makes the worker land on the
    # sub-goal, not anywhere inside the tolerance that a manager's own success test also spends.
    # Evaluation (``uniform_task``) always uses the env's.
    reach_d_th: float | None = Field(None, gt=0)  # m
    reach_theta_th_deg: float | None = Field(None, gt=0)


class TrainConfig(Strict):
    """A training run: the environment, the learner, and how long.

    ``kind: manager`` (default) trains a manager over the worker ``env.worker``; ``kind: worker`` trains
    the goToPoint worker itself on the task the ``gotopoint`` section describes (PPO only). ``algo:
    candidates`` reads neither ``num_envs``, ``total_steps`` nor the intervals: its own section says how
    long each phase runs and when it is scored.
    """

    name: str = "run"
    # One line for `hier-ssl configs`: what the config trains, in the words a reader picks one by.
    description: str = Field("", max_length=100, pattern=r"^[^\n]*$")
    kind: Literal["manager", "worker"] = "manager"
    env: EnvConfig = Field(default_factory=EnvConfig)
    # A multi-robot scenario in place of ``env``: one manager shared by every controlled robot (SAC or
    # candidates).
    scenario: ScenarioConfig | None = None
    gotopoint: GoToPointConfig | None = None
    algo: Literal["sac", "ppo", "candidates"] = "sac"
    sac: SACConfig = Field(default_factory=SACConfig)
    ppo: PPOConfig = Field(default_factory=PPOConfig)
    candidates: CandidatesConfig = Field(default_factory=CandidatesConfig)
    num_envs: int = Field(16, ge=1)
    total_steps: int = Field(150_000, ge=1)  # vector-env steps (manager decisions per env)
    eval_episodes: int = Field(200, ge=1)
    eval_interval: int = Field(500, ge=1)  # vector steps between selection evaluations
    # The best checkpoint is the one that ends the best stretch of this many selection evaluations (their
    # mean success rate, then mean CPAD). 1 ranks single evaluations; near 99 % success neighbouring
    # checkpoints differ by less than one evaluation's noise, and the single best is often a lucky one.
    selection_window: int = Field(1, ge=1)
    save_interval: int = Field(5_000, ge=1)  # vector steps between resumable checkpoints
    seed: int = 0
    device: str = "cpu"
    # The cores the run uses: torch's threads and the cores that step its fields' shards
    # (``hier_ssl.envs.shards``; the same episodes for every count); "auto": the cores the process may run
    # on. One by default: on a busy 2-core machine two OpenMP threads stall each other (90-200 ms per
    # update measured, against 11 ms on one thread); on an idle machine two threads save about a third.
    threads: Annotated[int, Field(ge=1)] | Literal["auto"] = 1

    @model_validator(mode="before")
    @classmethod
    def _default_gotopoint(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("kind") == "worker" and data.get("gotopoint") is None:
            data = {**data, "gotopoint": {}}
        return data

    @property
    def task_section(self) -> str:
        """The section the run's manager acts in: "scenario" when given, else "env"."""
        return "env" if self.scenario is None else "scenario"

    @property
    def task_config(self) -> TaskConfig:
        """What the run's manager acts in: the ``scenario`` section when given, else ``env``."""
        return getattr(self, self.task_section)

    @model_validator(mode="after")
    def _kind_consistent(self) -> TrainConfig:
        if self.scenario is not None:
            if "env" in self.model_fields_set and self.env != EnvConfig():
                raise ValueError("env: not read when 'scenario' is set; put the task keys in the scenario")
            if self.kind != "manager" or self.algo == "ppo":
                raise ValueError(
                    "scenario: trains a shared manager with SAC or candidates, "
                    f"not kind {self.kind!r}, algo {self.algo!r}"
                )
        if self.kind == "manager" and self.gotopoint is not None:
            raise ValueError("gotopoint: only read when kind is 'worker'")
        if self.algo != "candidates" and self.candidates != CandidatesConfig():
            raise ValueError(f"candidates: only read with algo 'candidates', got {self.algo!r}")
        if self.candidates.ppo.near_cost and self.task_config.observation == "paper":
            raise ValueError("candidates.ppo.near_cost reads the nearest neighbour; 'paper' has none")
        if self.algo != "sac" and self.sac.teacher is not None:
            raise ValueError(f"sac.teacher: only read with algo 'sac', got {self.algo!r}")
        if self.kind == "worker" and self.algo != "ppo":
            raise ValueError(f"algo: kind 'worker' trains with 'ppo', got {self.algo!r}")
        return self


def _section_model(annotation: Any) -> type[BaseModel] | None:
    """The model a field's annotation holds (``EnvConfig``, ``ScenarioConfig | None``,
    ``list[ObstacleConfig]``), or None."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    return next(filter(None, map(_section_model, typing.get_args(annotation))), None)


def did_you_mean(model: type[BaseModel], key: str) -> str:
    """A hint for an unknown ``key`` of ``model``: a key of it spelt alike, else the section of it that
    has the key (``; did you mean 'env.frame_skip'?``); empty when nothing fits."""
    fields = model.model_fields
    close = difflib.get_close_matches(key, fields, n=1)
    if close:
        return f"; did you mean {close[0]!r}?"
    for name, info in fields.items():
        section = _section_model(info.annotation)
        if section is not None and key in section.model_fields:
            return f"; did you mean '{name}.{key}'?"
    return ""


def _hint(model: type[BaseModel], loc: tuple[Any, ...]) -> str:
    """``did_you_mean`` for the unknown key at ``loc``, the model it was meant for found along the path."""
    section: type[BaseModel] | None = model
    for part in loc[:-1]:
        if isinstance(part, str) and section is not None:
            field = section.model_fields.get(part)
            section = None if field is None else _section_model(field.annotation)
    return "" if section is None else did_you_mean(section, str(loc[-1]))


def error_message(error: ErrorDetails) -> str:
    """One of a ValidationError's errors as words: pydantic's own messages ("Input should be 'drawn' or
    'team'") with the value that was given; our validators' (which name it) without their "Value error, "."""
    msg = error["msg"].removeprefix("Value error, ")
    given = error.get("input")
    if error["type"] not in ("value_error", "extra_forbidden", "missing") and not isinstance(given, dict):
        msg += f", not {given!r}"
    return msg


def _format(err: ValidationError, root: str, model: type[BaseModel]) -> str:
    first = err.errors()[0]
    path = ".".join(str(p) for p in (root, *first["loc"]) if p != "")
    hint = _hint(model, first["loc"]) if first["type"] == "extra_forbidden" else ""
    extra = "" if len(err.errors()) == 1 else f" (+{len(err.errors()) - 1} more)"
    # Our validators' messages start with the key they are about ("field: unknown preset ..."): that key
    # joins the path. Pydantic's "Value error, " prefix adds nothing.
    msg = error_message(first)
    if match := re.match(r"([A-Za-z_][\w.]*): (.*)", msg, re.DOTALL):
        path = ".".join(p for p in (path, match.group(1)) if p)
        msg = match.group(2)
    return f"{path}: {msg}{hint}{extra}" if path else f"{msg}{hint}{extra}"


def validate_config(data: dict[str, Any], model: type[BaseModel] = TrainConfig, root: str = "") -> Any:
    """Validate a plain dict into ``model`` by the models alone; raises ConfigError naming the first bad
    key. ``hier_ssl.envs.parse_config`` adds class defaults and the registries' checks."""
    try:
        return model.model_validate(copy.deepcopy(data))
    except ValidationError as err:
        raise ConfigError(_format(err, root, model)) from None


def dump_config(config: BaseModel) -> str:
    """The fully resolved config as YAML, written next to checkpoints (a scenario run without the ``env``
    section it does not read)."""
    exclude = {"env"} if isinstance(config, TrainConfig) and config.task_section == "scenario" else None
    return yaml.safe_dump(config.model_dump(mode="json", exclude=exclude), sort_keys=False)

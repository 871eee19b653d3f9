"""The candidate managers as one torch graph: observation -> scene -> the ``sampling`` planner's candidate
sub-goals -> each candidate's features -> the network's logits -> the chosen candidate -> the task's action.

Training (DAgger's and PPO's decisions), evaluation (``load_policy``) and the exported file
(``hier_ssl.policies.export``) all run this code, batched over (B scenes, C candidates, K obstacles): the
scene and the candidates in float64 (the planner's own candidates, which DAgger's labels name), the
features and the network in float32. TorchScript compiles ``CandidateManager.forward`` and ONNX traces it:
no complex dtype, no numpy, shapes fixed by the task (K, C) but the batch.

The scene is read from the manager observation as ``hier_ssl.manager.scene.read_scene`` reads it (the
float32 observation, neighbours turned into obstacles in the observation's units and rounded to float32);
the candidates are ``hier_ssl.manager.candidate_points``'s, the planner's own; the action is
``encode_subgoal``'s for a sub-goal at the candidate with the target's heading and no velocity.

``candidate_policy`` hands a manager to numpy callers; a residual with ``candidates.memory`` is a
``RememberingPolicy``, which keeps each robot's last sub-goal between calls.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from hier_ssl.config import TrainConfig
from hier_ssl.envs import make_scenario
from hier_ssl.manager.candidate_points import candidate_points
from hier_ssl.manager.game_observation import RuledPlanner, ruled_read
from hier_ssl.manager.planners import SamplingPlanner
from hier_ssl.policies.candidate_features import PathModel, candidate_features, feature_dim, path_model
from hier_ssl.policies.candidate_nets import Scorer
from hier_ssl.policies.candidate_residual import (
    Residual,
    residual_features,
    residual_inputs,
    residual_planner,
)
from hier_ssl.policies.networks import NumpyPolicy

Read = tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]
"""What ``CandidateGeometry.forward`` reads of observations: target (B, 4) x, y and the sine and cosine of
its heading (no arctangent: ONNX Runtime has none in float64); robot position and
velocity (B, 2); obstacle positions and velocities (B, K, 2); candidates (B, C, 2). Float64, m, rad, m/s."""


class CandidateGeometry(nn.Module):
    """Observations (B, O) float32 -> ``Read``; the features of its candidates; the action naming one.

    ``observation``: the layout read ("paper", "neighbours" or "encounters"); ``obstacles``: K, the
    obstacles the planner sees (the paper layout's obstacles, or the present neighbour slots, which every
    row has the same number of); ``action_form``, ``target_frame``: the task's actions."""

    def __init__(
        self,
        planner: SamplingPlanner,
        observation: str,
        obstacles: int,
        action_form: str,
        target_frame: bool,
    ) -> None:
        super().__init__()
        if observation not in ("paper", "neighbours", "encounters"):
            raise ValueError(f"unknown observation layout {observation!r}")
        self.paper, self.k = observation == "paper", obstacles
        self.max_pos = float(planner.max_pos or planner.field.max_pos)
        self.max_v = float(planner.robot.max_speed)
        model = path_model(planner)
        self.speed, self.hold, self.horizon = model.speed, model.hold, model.horizon
        self.safety, self.growth = model.safety, model.growth
        self.pose6, self.target_frame = action_form == "pose6", target_frame
        weights, turns = planner.candidate_maps(obstacles)
        self.register_buffer("weights", torch.from_numpy(weights))
        self.register_buffer("turns", torch.from_numpy(turns))
        half = torch.tensor([planner.field.half_length, planner.field.half_width], dtype=torch.float64)
        self.register_buffer("high", half)
        self.register_buffer("low", -half)

    @property
    def num_candidates(self) -> int:
        return self.weights.shape[0]

    def forward(self, obs: torch.Tensor) -> Read:
        x = obs.to(torch.float64)
        b, k = x.shape[0], self.k
        sincos = x[:, 2:4]
        radius = (sincos * sincos).sum(1, keepdim=True).sqrt()
        # A (0, 0) pair is heading 0, as atan2 reads it.
        sincos = torch.where(
            radius > 0, sincos / radius.clamp(min=1e-300), torch.cat([0 * radius, 1 + 0 * radius], 1)
        )
        target = torch.cat([x[:, 0:2] * self.max_pos, sincos], 1)
        robot, robot_vel = x[:, 6:8] * self.max_pos, x[:, 10:12] * self.max_v
        if self.paper:
            blocks = x[:, 13 : 13 + 5 * k].reshape(b, k, 5)
            pos, vel = blocks[:, :, 0:2], blocks[:, :, 2:4]
        else:  # neighbours as obstacles: own value plus the relative one, rounded as the numpy reader does
            blocks = x[:, 13 : 13 + 6 * k].reshape(b, k, 6)
            pos = (x[:, None, 6:8] + blocks[:, :, 0:2]).float().double()
            vel = (x[:, None, 10:12] + blocks[:, :, 2:4]).float().double()
        obstacles, velocities = pos * self.max_pos, vel * self.max_v
        points = torch.cat([target[:, None, 0:2], robot[:, None], obstacles], 1)
        cand = candidate_points(points, self.weights, self.turns, self.low, self.high)
        return target, robot, robot_vel, obstacles, velocities, cand

    def features(self, read: Read) -> torch.Tensor:
        """The candidates' features (B, C, F) float32 (``hier_ssl.policies.candidate_features``), computed
        in float32: twice as fast as float64 at batch 256, within 3e-4 of it, and finer than the float16
        DAgger stores them in."""
        target, robot, robot_vel, obstacles, velocities, cand = read
        model = PathModel(self.speed, self.hold, self.horizon, self.safety, self.growth)
        return candidate_features(model, target[:, 0:2], robot, robot_vel, obstacles, velocities, cand)

    def action(self, choice: torch.Tensor, read: Read) -> torch.Tensor:
        """The actions (B, A) float32 that name candidates ``choice`` (B,) of ``read`` as sub-goals with
        the target's heading and no velocity (``encode_subgoal``'s)."""
        target, cand = read[0], read[5]
        index = choice[:, None, None].expand(choice.shape[0], 1, 2)
        point = torch.gather(cand, 1, index)[:, 0]
        if self.target_frame:  # offsets cube-rooted; no turn from the target's heading: (sin, cos) = (0, 1)
            offset = ((point - target[:, 0:2]) / self.high).clamp(-1.0, 1.0)
            xy = offset.sign() * offset.abs() ** (1.0 / 3.0)
            sin = 0.0 * xy[:, 0:1]
            cos = sin + 1.0
        else:
            xy = (point / self.high).clamp(-1.0, 1.0)
            sin, cos = target[:, 2:3], target[:, 3:4]
        parts = [xy, 0.0 * xy] if self.pose6 else [xy]
        return torch.cat(parts + [sin, cos], 1).float()


class CandidateManager(nn.Module):
    """A classifier or scorer ``net`` over ``geometry``'s candidates: observations (B, O) float32 ->
    actions (B, A) float32 of the candidate of highest logit (``forward``, what the file exports), or of
    one drawn from the logits' softmax (``decide``)."""

    memory = False
    """Whether the decision reads each robot's last chosen sub-goal (``decide``'s ``last``): a residual's
    with ``candidates.memory``."""

    def __init__(self, geometry: CandidateGeometry, net: nn.Module) -> None:
        super().__init__()
        self.geometry, self.net = geometry, net
        self.scorer = isinstance(net, Scorer)
        if self.scorer and net.mean.shape[0] != feature_dim(geometry.k):
            raise ValueError(
                f"the scorer reads {net.mean.shape[0]} features a candidate; the task's {geometry.k} "
                f"obstacles give {feature_dim(geometry.k)}"
            )

    @classmethod
    def of(
        cls,
        geometry: CandidateGeometry,
        net: nn.Module,
        planner: SamplingPlanner | RuledPlanner,
        zone_features: bool = False,
        memory: bool = False,
    ) -> CandidateManager:
        """``net`` over ``geometry``'s candidates: a ``ResidualManager`` for a residual, which reads
        ``planner`` (and the zone clearances with ``zone_features``, ``candidates.zone_features``; the
        robot's last sub-goal with ``memory``, ``candidates.memory``)."""
        if isinstance(net, Residual):
            return ResidualManager(geometry, net, planner, zone_features, memory)
        return cls(geometry, net)

    def inputs(self, obs: torch.Tensor, read: Read) -> torch.Tensor:
        """What the network reads: the observations (classifier) or the candidates' features (scorer)."""
        if self.scorer:
            return self.geometry.features(read)
        return obs.float()

    def read(self, obs: torch.Tensor) -> Read:
        """The scene and candidates of observations (B, O) the network chooses among."""
        return self.geometry(obs)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        read = self.read(obs)
        choice = self.net(self.inputs(obs, read)).argmax(1)  # ties to the earlier candidate
        return self.geometry.action(choice, read)

    def decide(
        self,
        obs: np.ndarray,
        generator: torch.Generator | None = None,
        read: Read | None = None,
        last: np.ndarray | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, np.ndarray, torch.Tensor]:
        """The candidate each row chooses (B,) (highest logit, or drawn from the logits' softmax with
        ``generator``), its log-probability (B,), the action (B, A) naming it and what the network read;
        ``obs``'s ``read`` is built unless given; ``last`` (B,) complex, each robot's last chosen sub-goal
        (NaN: none), for a manager with ``memory``."""
        if last is not None and not self.memory:
            raise ValueError("this candidates manager keeps no memory (candidates.memory: false)")
        x = torch.as_tensor(obs, dtype=torch.float32)
        with torch.no_grad():
            read = self.read(x) if read is None else read
            inputs = self.inputs(x, read) if last is None else self.recall(x, read, last)
            logits = self.net(inputs)
            if logits.shape[1] != self.geometry.num_candidates:
                raise ValueError(
                    f"the network scores {logits.shape[1]} candidates, the planner builds "
                    f"{self.geometry.num_candidates} for these observations (another obstacle count or "
                    "planner)"
                )
            log_probs = torch.log_softmax(logits, 1)
            if generator is None:
                choice = logits.argmax(1)
            else:
                choice = torch.multinomial(log_probs.exp(), 1, generator=generator)[:, 0]
            action = self.geometry.action(choice, read).numpy()
        return choice, log_probs.gather(1, choice[:, None])[:, 0], action, inputs


class ResidualManager(CandidateManager):
    """A residual ``net`` (``hier_ssl.policies.candidate_residual``) over ``geometry``'s candidates, as
    ``CandidateManager``, reading ``planner``'s ranking and rollouts (and with ``zone_features`` the legs'
    zone clearances): numba and numpy, not one torch graph, so never exported."""

    def __init__(
        self,
        geometry: CandidateGeometry,
        net: nn.Module,
        planner: SamplingPlanner | RuledPlanner,
        zone_features: bool = False,
        memory: bool = False,
    ) -> None:
        super().__init__(geometry, net)
        residual_planner(planner)
        # The weights fix what the network reads, the run's config what is built for it: a run's config.yaml
        # that lost or gained the key would otherwise fail deep in a matrix product.
        reads, built = net.body[0].in_features, residual_features(zone_features, memory)
        if reads != built:
            raise ValueError(
                f"the residual reads {reads} features a candidate, candidates.zone_features: "
                f"{zone_features} and candidates.memory: {memory} build {built}"
            )
        self.planner, self.zone_features, self.memory = planner, zone_features, memory

    def read(self, obs: torch.Tensor) -> Read:
        """The geometry's read with the planner's own candidates: in a game, around the target moved where
        the rules let the robot go (``ruled_read``), where the geometry's are around the observed one (on
        2.5 % of ``game_stop``'s decisions, all of those where the two differed)."""
        read = self.geometry(obs)
        cand = self.planner.candidates(ruled_read(self.planner, obs.numpy())[0])
        return (*read[:5], torch.from_numpy(np.stack([cand.real, cand.imag], -1)))

    def inputs(self, obs: torch.Tensor, read: Read) -> torch.Tensor:
        """The planner's score and rollouts of ``read``'s candidates (``residual_inputs``); with
        ``memory``, as at an episode's first decision, with no sub-goal remembered."""
        return self.recall(obs, read, np.full(len(obs), np.nan + 0j) if self.memory else None)

    def recall(self, obs: torch.Tensor, read: Read, last: np.ndarray | None) -> torch.Tensor:
        """``inputs`` for robots whose last chosen sub-goals are ``last`` (B,) complex (NaN: none; None
        without ``memory``)."""
        return residual_inputs(self.planner, obs.numpy(), as_points(read[5]), self.zone_features, last)


class RememberingPolicy:
    """A candidates manager as a numpy policy with a memory per robot, the protocol of
    ``hier_ssl.envs.play.play``: ``forget(count)`` at the reset, then ``policy(obs, rows=...)`` for the
    robots ``rows`` (indices into the memory); without ``rows``, nothing remembered. The memory is each
    robot's last chosen sub-goal, which a residual with ``memory`` reads (``decide``'s ``last``)."""

    def __init__(
        self, manager: CandidateManager, generator: torch.Generator | None = None, count: int = 0
    ) -> None:
        self.manager, self.generator = manager, generator
        self.forget(count)

    def forget(self, count: int) -> None:
        self.last = np.full(count, np.nan + 0j)

    def decide(
        self, obs: np.ndarray, rows: np.ndarray
    ) -> tuple[torch.Tensor, torch.Tensor, np.ndarray, torch.Tensor]:
        """``CandidateManager.decide`` for the robots ``rows``, remembering the sub-goals they choose (a
        manager without ``memory`` reads none: nothing is kept)."""
        if not self.manager.memory:
            return self.manager.decide(obs, self.generator)
        with torch.no_grad():
            read = self.manager.read(torch.as_tensor(obs, dtype=torch.float32))
        decision = self.manager.decide(obs, self.generator, read, self.last[rows])
        self.last[rows] = as_points(read[5])[np.arange(len(obs)), decision[0].numpy()]
        return decision

    def __call__(self, obs: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        if rows is None:
            return self.manager.decide(obs, self.generator)[2]
        return self.decide(obs, rows)[2]


def candidate_policy(manager: CandidateManager, generator: torch.Generator | None = None) -> NumpyPolicy:
    """The manager as a numpy policy (``CandidateManager.decide``'s action); a live view of its weights.
    A manager with ``memory`` remembers each robot's last sub-goal (``RememberingPolicy``)."""
    if manager.memory:
        return RememberingPolicy(manager, generator)
    return lambda obs: manager.decide(obs, generator)[2]


def candidate_geometry(config: TrainConfig, planner: SamplingPlanner) -> CandidateGeometry:
    """The geometry of a run's task: its observation layout, the obstacles its planner sees, its actions."""
    env = config.task_config
    task = make_scenario(env)
    others = task.num_agents - 1 + task.num_obstacles
    seen = others if env.observation == "paper" else min(env.neighbours, others)
    return CandidateGeometry(planner, env.observation, seen, env.action_form, env.action_frame == "target")


def stored_features(
    geometry: CandidateGeometry, obs: np.ndarray, features: torch.Tensor | None = None
) -> np.ndarray:
    """What a scorer's DAgger keeps of observations ``obs`` (B, O): their candidates' features (built
    unless given), once per state rather than at every pass, in float16 for half the memory (the fit reads
    them rounded so, the policy in float32); 2,000 states at a time."""
    if features is not None:
        return features.numpy().astype(np.float16)
    parts = np.split(obs, range(2000, len(obs), 2000)) if len(obs) else [obs]
    with torch.no_grad():
        read = (geometry.features(geometry(torch.as_tensor(part))) for part in parts)
        return np.concatenate([part.numpy().astype(np.float16) for part in read])


def as_points(cand: torch.Tensor) -> np.ndarray:
    """Candidates (B, C, 2) as the planner's complex sub-goal positions (B, C)."""
    return cand.numpy().view(np.complex128)[..., 0]


__all__ = [
    "CandidateGeometry",
    "CandidateManager",
    "Read",
    "RememberingPolicy",
    "ResidualManager",
    "as_points",
    "candidate_geometry",
    "candidate_policy",
    "stored_features",
]

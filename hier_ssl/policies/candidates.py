"""A manager that chooses one of the ``sampling`` planner's candidate sub-goals: fitted to the planner by
DAgger, then improved on the task's own outcomes by PPO.

The planner's choice is discontinuous in the observation (pass an obstacle on the left or on the right),
and a Gaussian actor fitted to it lands between the branches. Here the manager's action is a class: one
of the planner's candidate sub-goals (``SamplingPlanner.candidates``: the target, the robot's position,
rings around each seen obstacle, points along the robot-target line, a ring around the robot), which the
planner builds from the observation by geometry alone. An MLP maps the observation to one logit per
candidate.

1. DAgger (Ross et al., 2011), ``rounds`` rounds: round 0 plays the planner, every later round the
   network; every state met is labelled with the planner's soft choice over all candidates (a softmax of
   minus the arrival time over the candidates of the best safety tier the planner would choose from,
   temperature ``tau`` seconds), and the network is refitted on everything gathered so far.
2. PPO (``ppo.iterations``; 0 skips it) on the categorical policy the logits define, from the DAgger
   fit, against the task's outcomes: per decision minus ``time_cost`` per 100 control steps, plus
   ``success_reward`` at a success, minus ``collision_cost`` at a collision. The planner's labels stop
   here; a KL penalty towards the DAgger fit (``kl_weight``) keeps the policy near what it learned there,
   and the value function is fitted alone for ``value_warmup`` iterations before the policy moves. This
   is what lets the manager improve on the planner rather than copy it.

A hybrid: at every decision the manager runs the planner's candidate geometry (not its rollouts, which
are where the planner's time goes), so it needs hier_ssl at run time and does not export.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.utils.tensorboard import SummaryWriter
from tqdm import tqdm

from hier_ssl.config import CandidatePPOConfig, TrainConfig
from hier_ssl.evaluate import evaluate
from hier_ssl.manager.planners import SamplingPlanner, Scene, make_planner

NumpyPolicy = Callable[[np.ndarray], np.ndarray]
Scorer = Callable[[NumpyPolicy, int, int, float, Callable[[], dict]], Any]
"""Model selection: ``(policy, step, transitions, train_time_s, state)``; ``state()`` is what
``best_actor.pt`` keeps (``hier_ssl.train``)."""


def candidate_planner(config: TrainConfig) -> SamplingPlanner:
    """The ``sampling`` planner of the run's task: its candidates are the manager's classes."""
    return make_planner("sampling", config.task_config)


def soft_choice(planner: SamplingPlanner, scene: Scene, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """The planner's candidates (N, C) complex and its soft choice over them (N, C), rows summing to 1.

    The tiers are ``SamplingPlanner.plan``'s: the candidates clear of the growing safety distance; failing
    those, the ones clear of the fixed distance; failing those, all, scored by the distance they keep from
    the obstacles instead of by arrival time. Within the tier a softmax of minus the score / ``tau``.
    """
    cand = planner.candidates(scene)
    arrival, clearance, hard, near = planner.rollout(scene, cand)
    safe, close = clearance >= 0.0, hard >= 0.0
    score = np.where(np.isfinite(near), near, 1e3)  # no obstacle at all: every candidate keeps clear
    score = np.where(close.any(1, keepdims=True), np.where(close, -arrival, -np.inf), score)
    score = np.where(safe.any(1, keepdims=True), np.where(safe, -arrival, -np.inf), score)
    weight = np.exp((score - score.max(1, keepdims=True)) / tau)
    return cand, weight / weight.sum(1, keepdims=True)


def mlp(sizes: list[int], activation: type[nn.Module]) -> nn.Sequential:
    """Linear layers of ``sizes`` with ``activation`` between them (none after the last)."""
    layers: list[nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:], strict=True):
        layers += [nn.Linear(a, b), activation()]
    return nn.Sequential(*layers[:-1])


def chooser(obs_dim: int, num_candidates: int, hidden: tuple[int, ...]) -> nn.Sequential:
    """The classifier: observations (B, obs_dim) -> one logit per candidate (B, C), ReLU between layers."""
    return mlp([obs_dim, *hidden, num_candidates], nn.ReLU)


def chooser_from_state(state: dict[str, torch.Tensor]) -> nn.Sequential:
    """The classifier rebuilt from its state dict, its sizes read from the weights."""
    keys = sorted((k for k in state if k.endswith(".weight")), key=lambda k: int(k.split(".")[0]))
    weights = [state[key] for key in keys]
    net = chooser(weights[0].shape[1], weights[-1].shape[0], tuple(w.shape[0] for w in weights[:-1]))
    net.load_state_dict(state)
    return net


def act(
    net: nn.Module, planner: SamplingPlanner, obs: np.ndarray, generator: torch.Generator | None = None
) -> tuple[torch.Tensor, torch.Tensor, np.ndarray]:
    """The candidate each row chooses (B,) (highest logit, or drawn from the logits' softmax with
    ``generator``), its log-probability (B,) and the action (B, A) that names it."""
    scene = planner.read(obs)
    cand = planner.candidates(scene)
    with torch.no_grad():
        logits = net(torch.as_tensor(obs, dtype=torch.float32))
    if logits.shape[1] != cand.shape[1]:
        raise ValueError(
            f"the network scores {logits.shape[1]} candidates, the planner builds {cand.shape[1]} "
            "for these observations (another obstacle count or planner)"
        )
    log_probs = torch.log_softmax(logits, 1)
    if generator is None:
        choice = logits.argmax(1)
    else:
        choice = torch.multinomial(log_probs.exp(), 1, generator=generator)[:, 0]
    chosen = cand[np.arange(len(cand)), choice.numpy()]
    action = planner.action(scene, planner.subgoals(scene, chosen)).astype(np.float32)
    return choice, log_probs.gather(1, choice[:, None])[:, 0], action


def candidate_policy(
    net: nn.Module, planner: SamplingPlanner, generator: torch.Generator | None = None
) -> NumpyPolicy:
    """The classifier as a numpy manager (``act``'s action); a live view of ``net``'s weights."""
    return lambda obs: act(net, planner, obs, generator)[2]


def outcome_reward(
    settings: CandidatePPOConfig,
    control_steps: np.ndarray,
    ended_rows: np.ndarray,
    success: np.ndarray,
    collision: np.ndarray,
) -> np.ndarray:
    """PPO's reward per row (R,) for one decision: minus ``time_cost`` per 100 control steps the decision
    took (``control_steps`` (R,)), plus ``success_reward`` / minus ``collision_cost`` on the rows
    ``ended_rows`` (E,) whose episodes ended in a success / collision (``success``, ``collision`` (E,))."""
    reward = -settings.time_cost * control_steps.astype(np.float32) / 100.0
    np.add.at(reward, ended_rows, settings.success_reward * success - settings.collision_cost * collision)
    return reward


def advantages(
    rewards: torch.Tensor,
    values: torch.Tensor,
    last_values: torch.Tensor,
    dones: torch.Tensor,
    gamma: float,
    lam: float,
) -> torch.Tensor:
    """Generalised advantage estimates (T, R) of a rollout: rewards, values, dones (T, R), the values of
    the observations after its last step (R,). A done step does not bootstrap (a truncation's bootstrap is
    already in its reward)."""
    out = torch.zeros_like(rewards)
    running = torch.zeros_like(last_values)
    for t in reversed(range(len(rewards))):
        following = last_values if t == len(rewards) - 1 else values[t + 1]
        keep = 1.0 - dones[t]
        delta = rewards[t] + gamma * following * keep - values[t]
        running = delta + gamma * lam * keep * running
        out[t] = running
    return out


def _seed(config: TrainConfig, phase: int, index: int) -> int:
    # Far from the selection and evaluation seeds (hier_ssl.train), so no training episode is theirs.
    return (config.seed + 1) * 1_000_000 + phase * 100_000 + index


class CandidateLearner:
    """Both phases over one run directory (module docstring). ``model.pt`` is rewritten after every DAgger
    round and every ``ppo.eval_interval`` PPO iterations, then ``score`` rates the greedy policy: curve
    step = the round, then rounds + the PPO iteration. A resumed PPO phase starts new episodes."""

    def __init__(self, config: TrainConfig, run_dir: Path, score: Scorer, progress: bool = True) -> None:
        self.config, self.run_dir, self.score = config, run_dir, score
        self.settings = config.candidates
        self.planner = candidate_planner(config)
        self.train_time = 0.0  # rollouts and updates, without the scoring
        self.net: nn.Sequential | None = None
        self.writer = SummaryWriter(run_dir)
        total = self.settings.rounds + self.settings.ppo.iterations
        self.bar = tqdm(total=total, desc="candidates (DAgger, then PPO)", disable=not progress)

    def learn(self, saved: dict[str, Any] | None = None) -> nn.Sequential:
        """Both phases, continuing ``saved`` (a ``model.pt``) where given; the final network."""
        torch.manual_seed(self.config.seed)
        saved = saved or {}
        if saved:
            torch.set_rng_state(saved["torch_rng"])
            self.train_time = saved["train_time_s"]
            self.net = chooser_from_state(saved["net"])
        try:
            if saved.get("phase", "dagger") == "dagger":
                self.dagger(saved)
                saved = {}
            if self.settings.ppo.iterations:
                self.ppo(saved)
        finally:
            self.bar.close()
            self.writer.close()
        assert self.net is not None
        return self.net

    def dagger(self, saved: dict[str, Any]) -> None:
        """Phase 1: ``rounds`` DAgger rounds, from round ``saved["round"] + 1`` where given."""
        settings, planner = self.settings, self.planner
        obs_parts = [saved["obs"].numpy()] if saved else []
        label_parts = [saved["labels"].numpy()] if saved else []
        optimizer = None
        if self.net is not None:
            optimizer = torch.optim.Adam(self.net.parameters(), lr=settings.learning_rate)
            optimizer.load_state_dict(saved["optimizer"])
        first = saved["round"] + 1 if saved else 0
        self.bar.update(first)

        def labelling(student: nn.Module | None) -> NumpyPolicy:
            def policy(obs: np.ndarray) -> np.ndarray:
                scene = planner.read(obs)
                cand, soft = soft_choice(planner, scene, settings.tau)
                obs_parts.append(np.asarray(obs, dtype=np.float32))
                label_parts.append(soft.astype(np.float32))
                if student is not None:
                    return act(student, planner, obs)[2]
                chosen = cand[np.arange(len(cand)), soft.argmax(1)]
                return planner.action(scene, planner.subgoals(scene, chosen))

            return policy

        for round_ in range(first, settings.rounds):
            began = time.perf_counter()
            seed = _seed(self.config, 0, round_)
            played = evaluate(labelling(self.net), self.config.task_config, settings.episodes, seed)
            x = torch.as_tensor(np.concatenate(obs_parts))
            p = torch.as_tensor(np.concatenate(label_parts))
            obs_parts, label_parts = [x.numpy()], [p.numpy()]
            if self.net is None:
                self.net = chooser(x.shape[1], p.shape[1], settings.hidden)
            net = self.net
            if optimizer is None:
                optimizer = torch.optim.Adam(net.parameters(), lr=settings.learning_rate)
            losses = []
            for _ in range(settings.epochs):
                for rows in torch.randperm(len(x)).split(settings.batch_size):
                    loss = -(p[rows] * torch.log_softmax(net(x[rows]), 1)).sum(1).mean()
                    optimizer.zero_grad()
                    loss.backward()
                    optimizer.step()
                    losses.append(loss.item())
            with torch.no_grad():
                agreement = float((net(x).argmax(1) == p.argmax(1)).float().mean())
            self.train_time += time.perf_counter() - began
            step = round_ + 1
            for key, value in (
                ("losses/cross_entropy", float(np.mean(losses))),
                ("dagger/first_choice_agreement", agreement),
                ("dagger/states", len(x)),
                ("episode/success_rate", played["success_rate"]),
                ("episode/collision_rate", played["collision_rate"]),
            ):
                self.writer.add_scalar(key, value, step)
            # Saved before the round is scored: a run killed while scoring resumes at the next round, and
            # the curve never holds a round twice.
            weights = {"net": net.state_dict(), "optimizer": optimizer.state_dict(), "obs": x, "labels": p}
            self.save({"phase": "dagger", "round": round_, "states": len(x), **weights})
            self.scored(step, len(x))
            self.bar.update(1)
            self.bar.set_postfix(states=len(x), agreement=f"{agreement:.2f}", played=played["success_rate"])
        self.states = len(obs_parts[0]) if obs_parts else 0

    def ppo(self, saved: dict[str, Any]) -> None:
        """Phase 2: ``ppo.iterations`` PPO iterations from the DAgger fit, from ``saved["iteration"]``."""
        from hier_ssl.envs.vector import TorchVectorEnv

        settings, planner, net = self.settings.ppo, self.planner, self.net
        assert net is not None
        obs_dim = net[0].in_features
        reference = copy.deepcopy(net) if not saved else chooser_from_state(saved["reference"])
        reference.requires_grad_(False)
        value = mlp([obs_dim, *settings.value_hidden, 1], nn.Tanh)
        policy_optimizer = torch.optim.Adam(net.parameters(), lr=settings.learning_rate)
        value_optimizer = torch.optim.Adam(value.parameters(), lr=settings.value_learning_rate)
        first, decisions = 0, 0
        if saved:
            value.load_state_dict(saved["value"])
            policy_optimizer.load_state_dict(saved["optimizer"])
            value_optimizer.load_state_dict(saved["value_optimizer"])
            first, decisions, self.states = saved["iteration"], saved["decisions"], saved["states"]
        self.bar.update(self.settings.rounds + first - self.bar.n)
        env = TorchVectorEnv(self.config.task_config, settings.fields)
        obs = env.reset_rows(seed=_seed(self.config, 1, first)).astype(np.float32)
        generator = torch.Generator().manual_seed(_seed(self.config, 1, first))
        for iteration in range(first, settings.iterations):
            began = time.perf_counter()
            rollout: dict[str, list] = {
                k: [] for k in ("obs", "choice", "log_prob", "reward", "done", "real")
            }
            ended = {"success": 0.0, "collision": 0.0, "episodes": 0}
            for _ in range(settings.horizon):
                # Rows of robots that have left are zeros until their field resets: no scene to plan in.
                real = obs.any(1)
                choice, log_prob = torch.zeros(len(obs), dtype=torch.long), torch.zeros(len(obs))
                action = np.zeros((len(obs), env.num_actions), dtype=np.float32)
                if real.any():
                    choice[real], log_prob[real], action[real] = act(net, planner, obs[real], generator)
                next_obs, _, terminated, truncated, info = env.step_rows(action)
                stats, rows = info["task"], info["task_rows"]
                reward = outcome_reward(
                    settings, info["control_steps"], rows, stats["success"], stats["collision"]
                )
                # A truncated episode would have gone on: its last decision bootstraps from the value of
                # the observation it ended on.
                cut = truncated & ~terminated
                if cut.any():
                    with torch.no_grad():
                        final = value(torch.as_tensor(info["final_obs"][cut], dtype=torch.float32))[:, 0]
                    reward[cut] += settings.gamma * final.numpy()
                ended["success"] += float(stats["success"].sum())
                ended["collision"] += float(stats["collision"].sum())
                ended["episodes"] += len(rows)
                for key, item in (
                    ("obs", obs), ("choice", choice), ("log_prob", log_prob), ("reward", reward),
                    ("done", terminated | truncated), ("real", real),
                ):  # fmt: skip
                    rollout[key].append(torch.as_tensor(item))
                obs = next_obs.astype(np.float32)
            o, choices, old_log_probs = (torch.stack(rollout[k]) for k in ("obs", "choice", "log_prob"))
            rewards = torch.stack(rollout["reward"]).float()
            dones = torch.stack(rollout["done"]).float()
            real = torch.stack(rollout["real"])
            with torch.no_grad():
                values = value(o).squeeze(-1)
                last = value(torch.as_tensor(obs)).squeeze(-1)
            adv = advantages(rewards, values, last, dones, settings.gamma, settings.lam)
            returns = adv + values
            batch = [t[real] for t in (o, choices, old_log_probs, adv, returns)]
            decisions += len(batch[0])
            moving = iteration >= settings.value_warmup
            logs = self.update(net, reference, value, policy_optimizer, value_optimizer, batch, moving)
            self.train_time += time.perf_counter() - began
            step = self.settings.rounds + iteration + 1
            if ended["episodes"]:
                logs["episode/success_rate"] = ended["success"] / ended["episodes"]
                logs["episode/collision_rate"] = ended["collision"] / ended["episodes"]
            for key, item in logs.items():
                self.writer.add_scalar(key, item, step)
            self.bar.update(1)
            if (iteration + 1) % settings.eval_interval == 0 or iteration + 1 == settings.iterations:
                weights = {
                    "net": net.state_dict(),
                    "reference": reference.state_dict(),
                    "value": value.state_dict(),
                    "optimizer": policy_optimizer.state_dict(),
                    "value_optimizer": value_optimizer.state_dict(),
                }
                progress = {"iteration": iteration + 1, "decisions": decisions, "states": self.states}
                self.save({"phase": "ppo", **progress, **weights})
                self.scored(step, self.states + decisions)

    def update(
        self,
        net: nn.Module,
        reference: nn.Module,
        value: nn.Module,
        policy_optimizer: torch.optim.Optimizer,
        value_optimizer: torch.optim.Optimizer,
        batch: list[torch.Tensor],
        moving: bool,
    ) -> dict[str, float]:
        """PPO's epochs over one rollout ``batch`` (obs, choices, log-probs, advantages, returns); the
        policy moves only when ``moving``. The losses of the last minibatch, for TensorBoard."""
        settings = self.settings.ppo
        obs, choices, old_log_probs, adv, returns = batch
        size = max(1, len(obs) // settings.minibatches)
        logs: dict[str, float] = {}
        for _ in range(settings.epochs):
            for rows in torch.randperm(len(obs)).split(size):
                value_loss = (value(obs[rows]).squeeze(-1) - returns[rows]).square().mean()
                value_optimizer.zero_grad()
                value_loss.backward()
                value_optimizer.step()
                logs["losses/value"] = value_loss.item()
                if not moving:
                    continue
                log_probs = torch.log_softmax(net(obs[rows]), 1)
                ratio = (log_probs.gather(1, choices[rows, None])[:, 0] - old_log_probs[rows]).exp()
                a = (adv[rows] - adv[rows].mean()) / (adv[rows].std() + 1e-8)
                clipped = ratio.clamp(1.0 - settings.clip, 1.0 + settings.clip)
                surrogate = -torch.min(ratio * a, clipped * a).mean()
                with torch.no_grad():
                    anchor = torch.log_softmax(reference(obs[rows]), 1)
                kl = (log_probs.exp() * (log_probs - anchor)).sum(1).mean()
                loss = surrogate + settings.kl_weight * kl
                policy_optimizer.zero_grad()
                loss.backward()
                policy_optimizer.step()
                logs |= {"losses/surrogate": surrogate.item(), "losses/kl_to_dagger": kl.item()}
        return logs

    def save(self, state: dict[str, Any]) -> None:
        from hier_ssl.policies.sac_runner import MODEL_FILE, atomic_save

        extra = {"train_time_s": self.train_time, "torch_rng": torch.get_rng_state()}
        atomic_save({**state, **extra}, self.run_dir / MODEL_FILE)

    def scored(self, step: int, transitions: int) -> None:
        assert self.net is not None
        kept = {"net": copy.deepcopy(self.net.state_dict()), "step": step}
        self.score(candidate_policy(self.net, self.planner), step, transitions, self.train_time, lambda: kept)


__all__ = [
    "CandidateLearner",
    "act",
    "advantages",
    "candidate_planner",
    "candidate_policy",
    "chooser",
    "chooser_from_state",
    "outcome_reward",
    "soft_choice",
]

"""A manager that chooses one of the ``sampling`` planner's candidate sub-goals: fitted to the planner by
DAgger, then improved on the task's own outcomes by PPO.

A Gaussian actor fitted to the planner's discontinuous choice (pass an obstacle left or right) lands
between the branches; here the action is a class, one of the planner's candidates, one logit each, from a
classifier over the observation, a scorer over each candidate's features or a residual over its ranking.

1. DAgger (Ross et al., 2011): round 0 plays the planner, later rounds the network; each state met labelled
   with the planner's soft choice (``soft_choice``), the network refitted on all (a residual: none).
2. PPO on the logits' categorical policy, from the DAgger fit, rewarded by outcomes alone (time, success,
   collision or the game's foul), a KL penalty towards the fit, a value fitted alone at first.

A classifier or scorer runs the planner's candidate geometry at every decision (not its rollouts, where
the planner's time goes), in torch: one graph (``candidate_graph``) that training, evaluation and
``hier-ssl export`` share. A residual runs the rollouts too, in numba, and does not export.
"""

from __future__ import annotations

import copy
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.utils.tensorboard import SummaryWriter
from tqdm import tqdm

from hier_ssl.checkpoints.tensors import load_checkpoint, save_checkpoint
from hier_ssl.config import ConfigError, TrainConfig
from hier_ssl.envs.planners import make_planner
from hier_ssl.envs.play import play
from hier_ssl.envs.shards import batched_core, close_core
from hier_ssl.envs.vector import TorchVectorEnv
from hier_ssl.manager.game_observation import RuledPlanner
from hier_ssl.manager.neighbours import nearest_gap
from hier_ssl.manager.planners import SamplingPlanner
from hier_ssl.policies.candidate_graph import (
    CandidateManager,
    RememberingPolicy,
    as_points,
    candidate_geometry,
    candidate_policy,
    stored_features,
)
from hier_ssl.policies.candidate_nets import build_chooser, chooser_from_state, fit_chooser, soft_choice
from hier_ssl.policies.learner import Checkpoint, OnCheckpoint, torch_threads
from hier_ssl.policies.networks import NumpyPolicy, mlp
from hier_ssl.policies.ppo import (
    categorical_kl,
    clipped_surrogate,
    gae,
    minibatches,
    normalized,
    outcome_reward,
    value_loss,
)
from hier_ssl.policies.sac_runner import MODEL_FILE


def candidate_planner(config: TrainConfig) -> SamplingPlanner | RuledPlanner:
    """``candidates.planner`` (a game's: ``RuledPlanner``): its candidates are the classes."""
    try:
        return make_planner(config.candidates.planner, config.task_config)
    except ValueError as error:  # a setting ``sampling`` lacks, a word for a number: named with the key
        raise ConfigError(f"candidates.planner: {error}") from None


def candidate_manager(config: TrainConfig, net: nn.Module) -> CandidateManager:
    """``net`` over the candidates of the run's ``sampling`` planner: the run's whole decision."""
    planner, chooser = candidate_planner(config), config.candidates
    geometry = candidate_geometry(config, planner)
    return CandidateManager.of(geometry, net, planner, chooser.zone_features, chooser.memory)


def _seed(config: TrainConfig, phase: int, index: int) -> int:
    # Far from the selection and evaluation seeds (hier_ssl.runs.train), so no training episode is theirs.
    return (config.seed + 1) * 1_000_000 + phase * 100_000 + index


def missing_keys(saved: dict[str, Any]) -> list[str]:
    """What a ``model.pt`` of ``CandidateLearner`` lacks for its phase (empty: it can be resumed)."""
    dagger, ppo = ("optimizer", "obs", "labels", "round"), ("reference", "value", "optimizers", "iteration")
    needs = {"dagger": dagger, "ppo": (*ppo, "decisions", "states")}
    wanted = ("net", "train_time_s", "torch_rng", *needs.get(saved.get("phase"), ("phase",)))
    return [key for key in wanted if key not in saved]


class CandidateLearner:
    """Both phases over one run directory, a ``Learner`` (``hier_ssl.policies.learner``) whose step is the
    DAgger round, then rounds + the PPO iteration. ``model.pt`` is rewritten after every DAgger round and
    every ``ppo.eval_interval`` PPO iterations, each then a checkpoint of the greedy policy. A resumed PPO
    phase starts new episodes."""

    def __init__(self, config: TrainConfig, run_dir: Path, progress: bool = True) -> None:
        self.config, self.run_dir = config, run_dir
        self.settings = config.candidates
        self.planner = candidate_planner(config)
        self.geometry = candidate_geometry(config, self.planner)
        self.train_time_s = 0.0  # rollouts and updates, without the checkpoints' scoring
        self.net: nn.Module | None = None
        self.writer = SummaryWriter(run_dir)
        total = self.settings.rounds + self.settings.ppo.iterations
        self.bar = tqdm(total=total, desc="candidates (DAgger, then PPO)", disable=not progress)
        self.resumed: dict[str, Any] = {}  # the model.pt that ``load`` read
        self.phase = "dagger"
        self.on_checkpoint: OnCheckpoint | None = None
        self.env: TorchVectorEnv | None = None

    def load(self, run_dir: str | Path) -> None:
        """Continue from ``run_dir``'s ``model.pt``, in the phase it was saved in."""
        path = Path(run_dir) / MODEL_FILE
        saved = load_checkpoint(path)
        if missing := missing_keys(saved):
            raise ConfigError(f"cannot resume {run_dir}: {path} lacks {missing}")
        self.resumed = saved

    def learn(self, total_steps: int, on_checkpoint: OnCheckpoint | None = None) -> None:
        """Both phases, from where ``load`` left them, until DAgger round ``total_steps`` or PPO iteration
        ``total_steps - rounds``."""
        torch.manual_seed(self.config.seed)
        saved, self.on_checkpoint = self.resumed, on_checkpoint
        if saved:
            self.train_time_s = saved["train_time_s"]
            self.net = chooser_from_state(saved["net"])
        try:
            if saved.get("phase", "dagger") == "dagger":
                self.dagger(saved, min(total_steps, self.settings.rounds))
                saved = {}
            iterations = min(total_steps - self.settings.rounds, self.settings.ppo.iterations)
            if iterations > 0:
                self.ppo(saved, iterations)
        finally:
            self.on_checkpoint = None
            self.bar.close()
            self.writer.close()
            if self.env is not None:  # the PPO phase's fields, with their worker processes
                self.env.close()

    def policy(self) -> NumpyPolicy:
        """The greedy choice of the network over the planner's candidates, a live view of its weights."""
        return candidate_policy(self.manager)

    def dagger(self, saved: dict[str, Any], rounds: int) -> None:
        """Phase 1: DAgger rounds until ``rounds``, from round ``saved["round"] + 1`` where given."""
        config, settings, planner, geometry = self.config, self.settings, self.planner, self.geometry
        obs_parts = [saved["obs"].numpy()] if saved else []
        label_parts = [saved["labels"].numpy()] if saved else []
        # A scorer's features of each state, kept as they were met (a resume rebuilds them from the states).
        scorer = settings.network == "scorer"
        input_parts = [stored_features(geometry, saved["obs"].numpy())] if saved and scorer else []
        optimizer = None
        if self.net is not None:
            optimizer = torch.optim.Adam(self.net.parameters(), lr=settings.learning_rate)
            optimizer.load_state_dict(saved["optimizer"])
        first = saved["round"] + 1 if saved else 0
        if saved:  # after the networks are built, whose initialisation draws from it
            torch.set_rng_state(saved["torch_rng"])
        self.bar.update(first)

        def labelling(student: nn.Module | None) -> NumpyPolicy:
            manager = None if student is None else CandidateManager(geometry, student)

            def policy(obs: np.ndarray) -> np.ndarray:
                x = torch.as_tensor(obs, dtype=torch.float32)
                read = geometry(x)  # the candidates the network chooses among are the ones labelled
                soft = soft_choice(planner, obs, as_points(read[5]), settings.tau)
                obs_parts.append(x.numpy())
                label_parts.append(soft.astype(np.float32))
                if manager is not None:  # the student reads the candidates and features built here
                    _, _, action, inputs = manager.decide(obs, None, read)
                    input_parts.extend([stored_features(geometry, obs, inputs)] if scorer else [])
                    return action
                if scorer:
                    input_parts.append(stored_features(geometry, obs, geometry.features(read)))
                return geometry.action(torch.as_tensor(soft.argmax(1)), read).numpy()

            return policy

        for round_ in range(first, rounds):
            began = time.perf_counter()
            core = batched_core(config.task_config, settings.episodes, False, threads=config.threads)
            with torch_threads(1):  # the fields' cores (hier_ssl.policies.learner); fits at the run's
                ends = play(core, labelling(self.net), _seed(config, 0, round_))
            close_core(core)  # its worker processes (on an error, when the core is collected)
            played = {"success_rate": ends["success"].mean(), "collision_rate": ends["collision"].mean()}
            x = torch.as_tensor(np.concatenate(obs_parts))
            p = torch.as_tensor(np.concatenate(label_parts))
            inputs = torch.as_tensor(np.concatenate(input_parts)) if scorer else x
            obs_parts, label_parts, input_parts = [x.numpy()], [p.numpy()], [inputs.numpy()] if scorer else []
            if self.net is None:  # a scorer's standardisation from the first round's states
                self.net = build_chooser(settings.network, settings.hidden, inputs.float(), p.shape[1])
            net = self.net
            if optimizer is None:
                optimizer = torch.optim.Adam(net.parameters(), lr=settings.learning_rate)
            loss, agreement = fit_chooser(net, optimizer, inputs, p, settings.epochs, settings.batch_size)
            self.train_time_s += time.perf_counter() - began
            step = round_ + 1
            for key, value in (
                ("losses/cross_entropy", loss),
                ("dagger/first_choice_agreement", agreement),
                ("dagger/states", len(x)),
                ("episode/success_rate", played["success_rate"]),
                ("episode/collision_rate", played["collision_rate"]),
            ):
                self.writer.add_scalar(key, value, step)
            # Saved before scoring: a run killed while scoring resumes at the next round, no curve row twice.
            self.dagger_round, self.optimizer, self.dagger_obs, self.dagger_labels = round_, optimizer, x, p
            self.save()
            self.checkpoint(step, len(x))
            self.bar.update(1)
            self.bar.set_postfix(states=len(x), agreement=f"{agreement:.2f}", played=played["success_rate"])
        self.states = len(obs_parts[0]) if obs_parts else 0

    def ppo(self, saved: dict[str, Any], iterations: int) -> None:
        """Phase 2: PPO iterations from the DAgger fit until ``iterations``, from ``saved["iteration"]``."""
        settings, chooser = self.settings.ppo, self.settings
        if self.net is None:  # no DAgger (a residual): PPO starts from the planner's own ranking
            residual = chooser.tau, chooser.keep, chooser.zone_features, chooser.memory
            self.net = build_chooser(chooser.network, chooser.hidden, None, 0, *residual)
        net, self.phase = self.net, "ppo"
        self.reference = copy.deepcopy(net) if not saved else chooser_from_state(saved["reference"])
        self.reference.requires_grad_(False)
        self.env = TorchVectorEnv(self.config.task_config, settings.fields, threads=self.config.threads)
        self.value = mlp(self.env.num_obs, settings.value_hidden, 1, nn.Tanh)
        self.optimizers = (
            torch.optim.Adam(net.parameters(), lr=settings.learning_rate),
            torch.optim.Adam(self.value.parameters(), lr=settings.value_learning_rate),
        )
        first, decisions = 0, 0
        if saved:
            self.value.load_state_dict(saved["value"])
            for optimizer, state in zip(self.optimizers, saved["optimizers"], strict=True):
                optimizer.load_state_dict(state)
            first, decisions, self.states = saved["iteration"], saved["decisions"], saved["states"]
            torch.set_rng_state(saved["torch_rng"])  # after the networks are built, as in dagger()
        self.bar.update(self.settings.rounds + first - self.bar.n)
        self.obs = self.env.reset_rows(seed=_seed(self.config, 1, first)).astype(np.float32)
        self.generator = torch.Generator().manual_seed(_seed(self.config, 1, first))
        self.memory = RememberingPolicy(self.manager, self.generator, len(self.obs))  # rows' last sub-goals
        if not saved and not self.settings.rounds:
            # A residual starts as the planner: scored as step 0, model selection can keep it where PPO
            # only makes it worse. Saved first, so a run killed while scoring does not score it twice.
            self.iteration, self.decisions = 0, 0
            self.save()
            self.checkpoint(0, self.states)
        for iteration in range(first, iterations):
            began = time.perf_counter()
            if settings.anneal:
                left = 1.0 - iteration / settings.iterations
                rates = (settings.learning_rate, settings.value_learning_rate)
                for optimizer, rate in zip(self.optimizers, rates, strict=True):
                    for group in optimizer.param_groups:
                        group["lr"] = rate * left
            with torch_threads(1):
                batch, logs = self.rollout()
            decisions += len(batch[0])
            logs |= self.update(batch, moving=iteration >= settings.value_warmup)
            self.train_time_s += time.perf_counter() - began
            step = self.settings.rounds + iteration + 1
            for key, item in logs.items():
                self.writer.add_scalar(key, item, step)
            self.bar.update(1)
            if (iteration + 1) % settings.eval_interval == 0 or iteration + 1 == iterations:
                self.iteration, self.decisions = iteration + 1, decisions
                self.save()
                self.checkpoint(step, self.states + decisions)

    def rollout(self) -> tuple[list[torch.Tensor], dict[str, float]]:
        """``ppo.horizon`` decisions of every field with the sampled policy: the live rows' observations,
        choices, log-probabilities, advantages and returns, and the success and collision rates of the
        episodes that ended (TensorBoard)."""
        settings, env, value = self.settings.ppo, self.env, self.value
        keys = ("obs", "choice", "log_prob", "reward", "done", "real")
        steps: dict[str, list] = {k: [] for k in keys}
        ended = np.zeros(3)  # successes, collisions, episodes
        read = []  # what the network read, live rows only: a scorer's features are not built twice
        for _ in range(settings.horizon):
            obs = self.obs
            # Rows of robots that have left are zeros until their field resets: no scene to plan in.
            real = obs.any(1)
            choice, log_prob = torch.zeros(len(obs), dtype=torch.long), torch.zeros(len(obs))
            action = np.zeros((len(obs), env.num_actions), dtype=np.float32)
            if real.any():
                decision = self.memory.decide(obs[real], np.flatnonzero(real))
                choice[real], log_prob[real], action[real], inputs = decision
                read.append(inputs)
            next_obs, _, terminated, truncated, info = env.step_rows(action)
            self.memory.last[terminated | truncated] = np.nan  # a new episode remembers nothing
            stats, rows = info["task"], info["task_rows"]
            failed = stats["collision"] + stats.get("foul", 0.0)  # a game's foul costs as a collision
            gap = nearest_gap(next_obs, self.geometry.max_pos) if settings.near_cost else None
            reward = outcome_reward(settings, info["control_steps"], rows, stats["success"], failed, gap)
            # A truncated episode would have gone on: its last decision bootstraps from the value of the
            # observation it ended on.
            cut = truncated & ~terminated
            if cut.any():
                with torch.no_grad():
                    final = value(torch.as_tensor(info["final_obs"][cut], dtype=torch.float32))[:, 0]
                reward[cut] += settings.gamma * final.numpy()
            ended += [stats["success"].sum(), failed.sum(), len(rows)]
            for key, item in zip(
                keys, (obs, choice, log_prob, reward, terminated | truncated, real), strict=True
            ):
                steps[key].append(torch.as_tensor(item))
            self.obs = next_obs.astype(np.float32)
        obs, choices, log_probs, rewards, dones, real = (torch.stack(steps[k]) for k in keys)
        with torch.no_grad():
            values = value(obs).squeeze(-1)
            last = value(torch.as_tensor(self.obs)).squeeze(-1)
        adv = gae(rewards.float(), values, last, dones.float(), settings.gamma, settings.lam)
        rates = {"episode/success_rate": ended[0], "episode/collision_rate": ended[1]}
        logs = {key: count / ended[2] for key, count in rates.items()} if ended[2] else {}
        live = [t[real] for t in (obs, choices, log_probs, adv, adv + values)]
        return [*live, torch.cat(read) if read else obs[real]], logs

    def update(self, batch: list[torch.Tensor], moving: bool) -> dict[str, float]:
        """PPO's epochs over one rollout ``batch`` (obs, choices, log-probs, advantages, returns, what the
        network read); the policy moves only when ``moving``. The losses of the last minibatch, for
        TensorBoard."""
        settings, net, value = self.settings.ppo, self.net, self.value
        assert net is not None
        policy_optimizer, value_optimizer = self.optimizers
        obs, choices, old_log_probs, adv, returns, inputs = batch
        logs: dict[str, float] = {}
        for rows in minibatches(len(obs), settings.minibatches, settings.epochs):
            fit = value_loss(value(obs[rows]).squeeze(-1), returns[rows])
            value_optimizer.zero_grad()
            fit.backward()
            value_optimizer.step()
            logs["losses/value"] = fit.item()
            if not moving:
                continue
            log_probs = torch.log_softmax(net(inputs[rows]), 1)
            taken = log_probs.gather(1, choices[rows, None])[:, 0]
            surrogate = clipped_surrogate(taken, old_log_probs[rows], normalized(adv[rows]), settings.clip)
            loss = surrogate
            if settings.kl_weight:  # the reference's forward pass costs a scorer as much as its own
                with torch.no_grad():
                    anchor = torch.log_softmax(self.reference(inputs[rows]), 1)
                kl = categorical_kl(log_probs, anchor)
                loss = loss + settings.kl_weight * kl
                logs["losses/kl_to_dagger"] = kl.item()
            policy_optimizer.zero_grad()
            loss.backward()
            policy_optimizer.step()
            logs["losses/surrogate"] = surrogate.item()
        return logs

    @property
    def manager(self) -> CandidateManager:
        """The network over the planner's candidates: the decision it plays."""
        assert self.net is not None
        zones, memory = self.settings.zone_features, self.settings.memory
        return CandidateManager.of(self.geometry, self.net, self.planner, zones, memory)

    def save(self) -> None:
        """``model.pt``: the network, the phase's progress (DAgger: the last round done, the states met
        and their labels; PPO: the iterations done, the reference, the value), its optimisers, the
        training time and torch's generator."""
        assert self.net is not None
        if self.phase == "dagger":
            state = {
                "phase": "dagger",
                "round": self.dagger_round,
                "states": len(self.dagger_obs),
                "net": self.net.state_dict(),
                "optimizer": self.optimizer.state_dict(),
                "obs": self.dagger_obs,
                "labels": self.dagger_labels,
            }
        else:
            progress = {"iteration": self.iteration, "decisions": self.decisions, "states": self.states}
            state = {
                "phase": "ppo",
                **progress,
                "net": self.net.state_dict(),
                "reference": self.reference.state_dict(),
                "value": self.value.state_dict(),
                "optimizers": [optimizer.state_dict() for optimizer in self.optimizers],
            }
        extra = {"train_time_s": self.train_time_s, "torch_rng": torch.get_rng_state()}
        save_checkpoint({**state, **extra}, self.run_dir / MODEL_FILE)

    def checkpoint(self, step: int, transitions: int) -> None:
        """Hand the greedy policy after ``step`` to ``on_checkpoint``; ``best_actor.pt`` keeps its net."""
        if self.on_checkpoint is None:
            return
        net = self.net
        assert net is not None

        def state() -> dict[str, Any]:
            return {"net": net.state_dict(), "step": step}

        self.on_checkpoint(Checkpoint(step, transitions, self.train_time_s, self.policy(), state))


__all__ = ["CandidateLearner", "candidate_manager", "candidate_planner", "missing_keys"]

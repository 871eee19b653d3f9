"""Measurement, not CI: why CAPS without frame skip left the sub-goal where it was (issue 31).

Short SAC runs of ``configs/TASK/caps.yaml`` (seed 0, ``--steps`` vector steps of 16 envs): the defaults
before the fix (``BEFORE``) with one group of keys changed per run, and the shipped file; then on 500
episode starts of the task, the mean action of the actor:

- spread: the standard deviation of its sub-goal's x and y over the starts, in action units (targets are
  uniform over the field: a sub-goal that follows them spreads by about 0.5; one that stays put by ~0);
- slope and miss (Proposed, where the reward is the sub-goal's distance from the target, so the best
  sub-goal is the target): the regression slope of the sub-goal's x and y on the target's (1 tracks it,
  below 1 shrinks towards the centre) and the median distance from the target, m;
- the norm of each actor-loss term's gradient on the actor's weights (a replay batch of 256): the critic's
  -Q, the entropy term alpha log pi, CAPS's spatial term on mean actions at the config's ``caps_lambda_s``
  (5 where CAPS is off: what it would add);
- success on 100 episodes (seed 123), mean action.

Run: python benchmarks/caps_without_skip.py [--task proposed] [--steps 3000] [--only defaults scale ...]
"""

from __future__ import annotations

import argparse
import tempfile

# The defaults until issue 31, where each run below starts (the shipped file has since changed these keys).
BEFORE = ["sac.reward_scale=0.1", "sac.caps_lambda_t=1", "sac.caps_lambda_s=5"]
VARIANTS = {
    "before": [],
    "scale": ["sac.reward_scale=1"],
    "alpha": ["sac.alpha=0.02"],
    "no-caps": ["sac.caps=false"],
    "scale-no-caps": ["sac.reward_scale=1", "sac.caps=false"],
    "scale-sampled": ["sac.reward_scale=1", "sac.caps_actions=sampled"],
    "scale-weights": ["sac.reward_scale=1", "sac.caps_lambda_t=0.1", "sac.caps_lambda_s=0.5"],
}
SHIPPED = "shipped"  # the config file as it is, no keys changed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", choices=["baseline", "proposed"], default="proposed")
    parser.add_argument("--steps", type=int, default=3000)
    names = [*VARIANTS, SHIPPED]
    parser.add_argument("--only", nargs="+", choices=names, default=names)
    args = parser.parse_args()

    import numpy as np
    import torch

    from hier_ssl.config.files import apply_overrides, config_dir, load_yaml
    from hier_ssl.envs import parse_config
    from hier_ssl.envs.core import HierarchicalCore
    from hier_ssl.envs.vector import TorchVectorEnv
    from hier_ssl.evaluation.evaluate import evaluate
    from hier_ssl.policies.networks import sac_policy
    from hier_ssl.policies.sac import caps_loss
    from hier_ssl.policies.sac_runner import SACRunner

    torch.set_num_threads(1)
    header = "run | keys | spread x, y | slope x, y | miss m | grad -Q | grad entropy | grad CAPS | success %"
    print(f"| {header} |\n|" + "---|" * 9)
    for name in args.only:
        sets = [] if name == SHIPPED else BEFORE + VARIANTS[name]
        config = parse_config(apply_overrides(load_yaml(config_dir() / f"{args.task}/caps.yaml"), sets))
        env = TorchVectorEnv(config.task_config, config.num_envs)
        with tempfile.TemporaryDirectory() as run_dir:
            runner = SACRunner(env, config.sac, run_dir, seed=0, progress=False, save_interval=10**9)
            runner.learn(args.steps)
        sac, cfg = runner.sac, config.sac
        # Each term's gradient on the actor's weights, on one replay batch.
        data = sac.replay.sample(256, torch.Generator().manual_seed(0))
        params = list(sac.actor.parameters())
        pi, log_pi = sac.actor(data.obs, sac.generator)
        spatial = caps_loss(
            sac.actor.deterministic, data.obs, data.next_obs, 0.0, cfg.caps_lambda_s, cfg.caps_sigma
        )[1]
        terms = (
            -sac.qf(data.obs, pi).min(dim=0).values.mean(),
            (sac.log_alpha.exp() * log_pi).mean(),
            spatial,
        )
        grads = []
        for term in terms:
            g = torch.autograd.grad(term, params, retain_graph=True)
            grads.append(float(torch.sqrt(sum((x * x).sum() for x in g))))
        # The mean sub-goal at 500 episode starts against the target (observation columns 0-1: target x, y).
        core = HierarchicalCore(config.task_config, 500, autoreset=False)
        obs = np.asarray(core.reset(seed=5)).reshape(500, -1)
        scales = core.scenario.scales
        action = sac_policy(sac.actor)(obs)
        target = obs[:, 0:2] * scales["max_pos"]
        subgoal = action[:, 0:2] * np.array([scales["half_length"], scales["half_width"]])
        slope = [np.polyfit(target[:, k], subgoal[:, k], 1)[0] for k in (0, 1)]
        miss = np.median(np.linalg.norm(subgoal - target, axis=1))
        success = evaluate(sac_policy(sac.actor), config.task_config, 100, seed=123)["success_rate"]
        spread = action[:, 0:2].std(axis=0)
        keys = ", ".join(f"`{s}`" for s in VARIANTS.get(name, [])) or "-"
        print(
            f"| {name} | {keys} | {spread[0]:.3f}, {spread[1]:.3f} | {slope[0]:.2f}, {slope[1]:.2f} | "
            f"{miss:.2f} | {grads[0]:.2f} | {grads[1]:.2f} | {grads[2]:.2f} | {100 * success:.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()

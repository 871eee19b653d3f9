"""Measurement, not CI: throughput of the multi-robot vector view on ``formation`` (6 controlled robots + 6
moving obstacles per Division B field) on one core.

Uniform random manager actions (so robots collide, stop and touch, as early in training), frame skip 16,
auto-reset; the policy's cost is not included. A field-step is one 25 ms control step of one field:
workers, obstacles, physics, contacts, rewards, success and collision checks, plus each decision's
observations and resets spread over its control steps. Prints the best of ``--repeats`` runs of
``--decisions`` vector steps: field-steps/s (control steps/s of all fields), robot-steps/s (x 12),
manager decisions/s (rows x vector steps), and the share of the time spent inside ``World.step``.

Run: python benchmarks/formation.py [--fields 256] [--decisions 10] [--repeats 5]
"""

from __future__ import annotations

import argparse
import time

from hier_ssl.bench import pin_to_one_core


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fields", type=int, default=256)
    parser.add_argument("--decisions", type=int, default=10, help="vector steps per timed run")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--scenario", default="formation")
    args = parser.parse_args()
    cpu = pin_to_one_core()

    import torch

    from hier_ssl.envs import scenario_config
    from hier_ssl.envs.vector import TorchVectorEnv

    env = TorchVectorEnv(scenario_config(args.scenario), args.fields)
    core, world = env.core, env.core.world
    robots = core.num_agents + core.num_obstacles
    # Time spent in the physics, measured by wrapping this one World's step.
    world_step, in_world = world.step, [0.0]

    def timed_step(command):  # noqa: ANN001, ANN202 - a benchmark shim with World.step's signature
        start = time.perf_counter()
        state = world_step(command)
        in_world[0] += time.perf_counter() - start
        return state

    world.step = timed_step
    generator = torch.Generator().manual_seed(0)
    env.reset(seed=0)

    def run(decisions: int) -> tuple[float, int, float]:
        in_world[0], first = 0.0, core.control_steps
        start = time.perf_counter()
        for _ in range(decisions):
            env.step(torch.rand(env.num_envs, env.num_actions, generator=generator) * 2.0 - 1.0)
        return time.perf_counter() - start, core.control_steps - first, in_world[0]

    run(3)
    best = min((run(args.decisions) for _ in range(args.repeats)), key=lambda r: r[0] / r[1])
    wall, steps, physics = best
    field_steps = args.fields * steps / wall
    where = f"CPU {cpu}" if cpu is not None else "one thread"
    print(f"{args.scenario}: {args.fields} fields x {robots} robots ({core.num_agents} controlled), {where}")
    print(f"  field-steps/s    {field_steps:12,.0f}   (control steps/s of all fields)")
    print(f"  robot-steps/s    {field_steps * robots:12,.0f}")
    print(f"  decisions/s      {env.num_envs * args.decisions / wall:12,.0f}   (manager rows x vector steps)")
    print(f"  per control step {wall / steps * 1e3:9.2f} ms, {100 * physics / wall:.0f} % in World.step")


if __name__ == "__main__":
    main()

"""Measurement, not CI: a team of 11 decided in one batched planner call, under the rules and without.

Division A, the referee in STOP: 11 yellow robots (keeper id 0) and 11 blue ones at random places, the ball
at a random spot, every yellow robot a random target; each robot sees its ``--obstacles`` nearest other
robots (the "paper" observation). Each yellow robot's zones come from ``forbidden_zones`` (the walls, its own
defense area, the opponent's defense area, the ball in STOP) and its limit from ``speed_limit`` (1.5 m/s).
Every call decides the 11 robots of one such state (batch 11, one call); ``--states`` different states,
after ``--warmup`` calls. ``trajectory`` is called with rows (its memory of winners, as ``play`` calls it).
Prints, per planner and with / without the rules, the median and 90th percentile per call and the median
per robot, and the median CPU time of the process per call (on a machine shared with other work, the wall
time includes waiting for the core; the CPU time less so). The process is pinned to one core (``--core``);
numpy's elementwise work is one thread anyway.

Run: python benchmarks/team_decision.py [--states 200] [--obstacles 5] [--core 0] [--profile sampling]
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import os
import pstats
import time

import numpy as np

from hier_ssl.envs import env_config
from hier_ssl.envs.planners import make_planner
from hier_ssl.game import referee as ref
from hier_ssl.game.legal import row_rules
from hier_ssl.game.zones import forbidden_zones, speed_limit
from hier_ssl.manager import manager_observation
from hier_ssl.world.field import get_field

FIELD = get_field("division_a")
TEAM = 11


def team_states(count: int, obstacles: int, seed: int) -> tuple[list[np.ndarray], list]:
    """``count`` states: manager observations (11, 13 + 5K) of the yellow team and their ``RowRules``."""
    rng = np.random.default_rng(seed)
    robots = ref.lineup(np.repeat([ref.YELLOW, ref.BLUE], TEAM), np.tile(np.arange(TEAM), 2), FIELD)
    state = ref.referee_state(ref.STOP, FIELD, keeper=(0, 0))
    half = np.array([FIELD.half_length, FIELD.half_width])
    observations, rules = [], []
    for _ in range(count):
        pos = rng.uniform(-half, half, (2 * TEAM, 2))
        vel = rng.normal(0.0, 0.5, (2 * TEAM, 2))
        ball = rng.uniform(-half + 0.5, half - 0.5, (1, 2))
        target = np.concatenate([rng.uniform(-half, half, (TEAM, 2)), np.zeros((TEAM, 3))], axis=1)
        gaps = np.linalg.norm(pos[:TEAM, None] - pos[None], axis=-1)
        gaps[np.arange(TEAM), np.arange(TEAM)] = np.inf
        near = np.argsort(gaps, axis=1)[:, :obstacles]
        observations.append(
            manager_observation(
                target,
                pos[:TEAM],
                np.zeros(TEAM),
                vel[:TEAM],
                np.zeros(TEAM),
                pos[near],
                vel[near],
                np.zeros((TEAM, obstacles)),
                max_pos=FIELD.max_pos,
            )
        )
        zones = forbidden_zones(state, ball, FIELD, robots)
        yellow = dataclasses.replace(
            zones, kind=zones.kind[:, :TEAM], shape=zones.shape[:, :TEAM], clearance=zones.clearance[:, :TEAM]
        )
        rules.append(row_rules(yellow, speed_limit(state)))
    return observations, rules


def planner(name: str):
    made = make_planner(name, env_config(task="obstacle"))
    if name == "trajectory":
        made.field, made.max_pos = FIELD, FIELD.max_pos
        made.forget(TEAM)
        return made
    return dataclasses.replace(made, field=FIELD, max_pos=FIELD.max_pos)


def decide(made, name: str, obs: np.ndarray, rules) -> np.ndarray:
    if name == "trajectory":
        return made(obs, rows=np.arange(TEAM), rules=rules)
    return made(obs, rules=rules)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--states", type=int, default=200)
    parser.add_argument("--warmup", type=int, default=20)
    parser.add_argument("--obstacles", type=int, default=5)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--core", type=int, default=0)
    parser.add_argument("--profile", default=None, help="a planner to profile under the rules, after timing")
    args = parser.parse_args()
    os.sched_setaffinity(0, {args.core})
    observations, rules = team_states(args.states + args.warmup, args.obstacles, args.seed)
    print(
        f"division_a, STOP, a team of {TEAM} per call, {args.obstacles} obstacles each, {args.states} states"
    )
    for name in ("direct", "sampling", "trajectory"):
        for ruled in (False, True):
            made, times, cpu = planner(name), [], []
            for i, (obs, rule) in enumerate(zip(observations, rules, strict=True)):
                start, start_cpu = time.perf_counter(), time.process_time()
                decide(made, name, obs, rule if ruled else None)
                if i >= args.warmup:
                    times.append(time.perf_counter() - start)
                    cpu.append(time.process_time() - start_cpu)
            median, p90 = np.median(times) * 1e3, np.percentile(times, 90) * 1e3
            label = "rules" if ruled else "none"
            print(
                f"  {name:10s} {label:5s} median {median:7.2f} ms, p90 {p90:7.2f} ms per call, "
                f"{median / TEAM:5.2f} ms per robot; CPU median {np.median(cpu) * 1e3:7.2f} ms"
            )
    if args.profile:
        made = planner(args.profile)
        profile = cProfile.Profile()
        profile.enable()
        for obs, rule in zip(observations, rules, strict=True):
            decide(made, args.profile, obs, rule)
        profile.disable()
        pstats.Stats(profile).sort_stats("cumulative").print_stats(25)


if __name__ == "__main__":
    main()

"""Seeded episodes pinned to the numbers the code gave before the paper tasks and the scenarios shared one
core (commit 7459b17): training runs of the paper's tables were started on that code, so the same config
and seed must still give the same starts, targets, obstacle motion and rewards.

Tolerances allow for libm differences between CPUs (a few units in the last place of a sine, grown over
a handful of physics steps), not for a change of semantics, which moves these numbers by far more.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

import hier_ssl

CONFIGS = Path(__file__).parents[2] / "configs"
# Baseline by its name, our reward's keys: the Baseline FSCAPS default of that commit, which now ships the
# public code's reward (configs/baseline/fscaps.yaml); the others are still their FSCAPS defaults' files.
SOURCES = {
    "baseline": "baseline",
    "proposed": CONFIGS / "proposed" / "fscaps.yaml",
    "obstacle": CONFIGS / "obstacle" / "fscaps.yaml",
}
ACTIONS = [[0.3, -0.2, 0.0, 1.0], [-0.5, 0.4, 0.6, 0.8], [0.0, 0.0, 0.0, 1.0]]
OBS0 = [0.20904678106307983, -0.23021328449249268, -0.8928691148757935, -0.45031625032424927, 0.0, 0.0]
OBS0 += [0.16275987029075623, 0.2294965535402298, 0.780806303024292, -0.6247731447219849, 0.0, 0.0, 0.0]
PINNED = {
    "baseline": {
        "obs0": OBS0,
        "rewards": [
            [-40.135433197021484, -71.8279037475586, -58.20805740356445],
            [-33.94253158569336, -68.83247375488281, -46.089088439941406],
            [-25.10996437072754, -63.106197357177734, -34.26895523071289],
        ],
        "pos": [[0.8550864368040463, -0.19704633537149185]],
        "angle": [0.19639113334440506],
    },
    "proposed": {
        "obs0": OBS0,
        "rewards": [[-18.161684036254883, -54.456233978271484, -39.731666564941406]] * 3,
        "pos": [[0.8550864368040463, -0.19704633537149185]],
        "angle": [0.19639113334440506],
    },
    "obstacle": {
        "obs0": OBS0[:2]
        + [-0.9516143798828125, 0.3072948455810547]
        + OBS0[4:]
        + [0.023143459111452103, -0.22985492646694183, 0.0, 0.0, 0.0, 1.0],
        # Field 0 collides in its second decision and starts over.
        "rewards": [
            [10.442110061645508, -7.75175666809082, 174.5082550048828],
            [-9991.515625, -7.727845668792725, 174.4687042236328],
            [10.004754066467285, -7.715526580810547, 174.4646759033203],
        ],
        "pos": [[0.666815037905409, -1.2420146431952817], [1.040166111441321, -0.8175401061668051]],
        "angle": [2.9281081283478647, -1.2996231734403643],
    },
}


@pytest.mark.parametrize("task", sorted(PINNED))
def test_paper_task_episodes_are_those_of_the_code_the_paper_runs_started_on(task: str) -> None:
    pinned = PINNED[task]
    env = hier_ssl.vector_env(SOURCES[task], num_envs=3, frame_skip=16)
    obs = env.reset(seed=0)
    np.testing.assert_allclose(obs[0].numpy(), pinned["obs0"], rtol=1e-6, atol=1e-7)
    rewards = [env.step(torch.tensor(ACTIONS))[1].tolist() for _ in range(3)]
    np.testing.assert_allclose(rewards, pinned["rewards"], rtol=1e-6)
    state = env.core.world.state
    np.testing.assert_allclose(state.pos[0], pinned["pos"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(state.angle[0], pinned["angle"], rtol=0, atol=1e-9)


def test_formation_episode_is_the_one_of_the_multi_robot_core() -> None:
    env = hier_ssl.scenario_vector_env(CONFIGS / "scenarios" / "formation.yaml", num_fields=2)
    env.reset(seed=0)
    generator = torch.Generator().manual_seed(0)
    rewards = [env.step(torch.rand(12, 4, generator=generator) * 2 - 1)[1].tolist() for _ in range(2)]
    np.testing.assert_allclose(
        rewards,
        [
            [-13.886148452758789, 11.727204322814941, -2.7417125701904297, -21.290285110473633]
            + [-15.908269882202148, -29.100648880004883, 147.7847442626953, -21.554882049560547]
            + [-27.967985153198242, -21.66914176940918, -14.701559066772461, -34.338626861572266],
            [-7.871713638305664, -5002.44287109375, -14.518033027648926, -9.561726570129395]
            + [3.9933407306671143, -53.669471740722656, -25.887100219726562, -38.32429885864258]
            + [-72.53764343261719, 155.5895538330078, -13.449957847595215, -38.247154235839844],
        ],
        rtol=1e-6,
    )
    np.testing.assert_allclose(
        env.core.world.state.pos[0, :3],
        [[0.14502738230491796, 0.8315535982540772], [-0.0387957960457618, 2.0243549054133587]]
        + [[1.858698375752477, -2.874125512147289]],
        rtol=0,
        atol=1e-9,
    )

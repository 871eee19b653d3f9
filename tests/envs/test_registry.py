"""Where configs enter from keyword arguments and ``--set`` items: unknown keys are named, with a hint, and
every command takes a key spelt as ``train`` spells it."""

from __future__ import annotations

import gymnasium
import pytest

import hier_ssl
from hier_ssl.config import ConfigError, UnknownSettingError
from hier_ssl.envs import load_config, parse_config, task_config

CONSTRUCTORS = {
    "parallel_env": lambda **kw: hier_ssl.parallel_env(task="proposed", **kw),
    "env": lambda **kw: hier_ssl.envs.env(task="proposed", **kw),
    "manager_env": lambda **kw: hier_ssl.manager_env(task="proposed", **kw),
    "manager_vector_env": lambda **kw: hier_ssl.manager_vector_env(task="proposed", num_fields=2, **kw),
    "vector_env": lambda **kw: hier_ssl.vector_env(task="proposed", num_envs=2, **kw),
    "scenario_env": lambda **kw: hier_ssl.scenario_env("crossing", **kw),
    "gymnasium.make": lambda **kw: gymnasium.make("hier_ssl/Proposed-v0", **kw),
    "gymnasium.make_vec": lambda **kw: gymnasium.make_vec("hier_ssl/Proposed-v0", num_envs=2, **kw),
}


@pytest.mark.parametrize("make", CONSTRUCTORS.values(), ids=CONSTRUCTORS)
def test_an_unknown_keyword_argument_is_a_type_error_naming_it(make) -> None:
    # Python's own words for it: TorchRL's GymEnv passes frameskip= and retries without it on exactly this.
    with pytest.raises(TypeError, match="unexpected keyword argument 'frameskip'; did you mean 'frame_skip'"):
        make(frameskip=4)
    with pytest.raises(ConfigError, match="frameskip"):
        make(frameskip=4)
    assert issubclass(UnknownSettingError, TypeError) and issubclass(UnknownSettingError, ConfigError)


def test_set_takes_the_training_configs_spelling_in_every_command() -> None:
    assert task_config("proposed", ["env.frame_skip=4"]).frame_skip == 4
    assert task_config("proposed", ["frame_skip=4"]).frame_skip == 4  # the task's own spelling still
    assert task_config("crossing", ["scenario.num_agents=3"]).num_agents == 3
    assert task_config("configs/scenarios/crowd.yaml", ["scenario.num_obstacles=2"]).num_obstacles == 2
    assert load_config("proposed/fscaps", ["env.frame_skip=4"]).env.frame_skip == 4


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: task_config("proposed", ["frame_skp=4"]), "env.frame_skp: .*did you mean 'frame_skip'"),
        (lambda: task_config("crossing", ["num_agent=3"]), "scenario.num_agent: .*did you mean 'num_agents'"),
        (lambda: load_config("proposed/fscaps", ["frame_skip=4"]), "did you mean 'env.frame_skip'"),
        (
            lambda: load_config("proposed/fscaps", ["sac.actor_lrr=1"]),
            "sac.actor_lrr: .*did you mean 'actor_lr'",
        ),
        (lambda: parse_config({"env": {"obstacles": [{"behavior": "x"}]}}), "0.behavior: .*'behaviour'"),
    ],
)
def test_an_unknown_set_key_gets_a_did_you_mean(build, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as caught:
        build()
    assert not isinstance(caught.value, TypeError)  # a config's key, not a keyword argument

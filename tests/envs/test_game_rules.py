"""The rules in the game scenarios: bad settings refused by name, HALT, fouls that end an episode as fouls
(crashes among them, slower contacts staying collisions), STOP's new role positions, the rules in the
manager observation and read back from it, a scripted planner under them, the render and the evaluation."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import hier_ssl
from hier_ssl.config import ConfigError
from hier_ssl.envs import HierarchicalCore, Scenario, make_scenario, scenario_config
from hier_ssl.envs.game import (
    COLLIDED,
    FOULED,
    IN_PLAY,
    MARK_DISTANCE,
    SUCCEEDED,
    assign_roles,
    game_outcome,
    rest_point,
)
from hier_ssl.envs.planners import make_planner
from hier_ssl.envs.play import play
from hier_ssl.evaluation.evaluate import evaluate
from hier_ssl.evaluation.figures import _panel, label_outcomes, panel_title
from hier_ssl.evaluation.report import csv_table, make_record, markdown_table
from hier_ssl.game import (
    DIRECT_FREE_BLUE,
    FORCE_START,
    KINDS,
    STOP,
    forbidden_zones,
    signed_distance,
    speed_limit,
)
from hier_ssl.game.legal import SPEED_MARGIN, row_rules
from hier_ssl.game.referee import IN_PLAY_DISTANCE
from hier_ssl.game.zones import STOP_SPEED
from hier_ssl.manager.game_observation import (
    GAME_OBS_DIM,
    GAME_OBS_SLICES,
    REFEREE_FLAGS,
    game_rules,
    robot_position,
)

SMALL = {"num_agents": 2, "num_obstacles": 2, "max_steps": 40, "frame_skip": 1}


def _core(name: str, fields: int = 1, **settings: object) -> HierarchicalCore:
    core = HierarchicalCore(scenario_config(name, **{**SMALL, **settings}), fields, autoreset=False)
    core.reset(seed=0)
    return core


@pytest.mark.parametrize(
    ("name", "settings", "words"),
    [
        (
            "game_stop",
            {"options": {"command": "PREPARE_KICKOFF_BLUE"}},
            "options.command: .*'PREPARE_KICKOFF_BLUE'",
        ),
        ("game_ball_placement", {"options": {"placement": [5.0, 0.5]}}, r"options.placement.*\(5, 0.5\)"),
        (
            "game_stop",
            {"num_agents": 7},
            "num_agents: the yellow team has 7 robots; division_b allows at most 6",
        ),
        ("game_free_kick", {"num_obstacles": 7}, "num_obstacles: the blue team has 7 robots"),
        ("game_stop", {"options": {"keeper": 6}}, "options.keeper: keeper id 6 of the yellow team"),
        (
            "game_stop",
            {"options": {"opponent_keeper": 9}},
            "options.opponent_keeper: keeper id 9 of the blue",
        ),
        ("game_match", {"obstacles": {"behaviour": "random_walk"}}, "obstacles.behaviour: 'random_walk'"),
        ("game_stop", {"hit_mode": "replace"}, "hit_mode: 'replace'"),
        ("game_ball_placement", {"options": {"assign": "nearest"}}, "options.assign: .*'nearest'"),
        (
            "game_stop",
            {"options": {"command_at": [2.0, 1.0]}},
            r"options.command_at: .*\(2.0, 1.0\) is no range",
        ),
    ],
)
def test_bad_settings_are_refused_naming_the_key_and_the_value(name: str, settings: dict, words: str) -> None:
    with pytest.raises(ConfigError, match=f"scenario.{words}"):
        scenario_config(name, **settings)


def test_halt_stops_every_robot_ours_and_theirs() -> None:
    core = _core("game_free_kick", options={"command": "HALT"})
    pos = core.state.pos.copy()
    core.step(np.ones((1, 2, core.act_dim)))  # sub-goals in a corner: the workers would drive
    np.testing.assert_array_equal(core.state.vel, 0.0)
    np.testing.assert_allclose(core.state.pos, pos, atol=1e-9)


@pytest.mark.parametrize(("guard", "top"), [(SPEED_MARGIN, SPEED_MARGIN * STOP_SPEED), (None, 2.2)])
def test_the_speed_guard_caps_our_robots_under_stop_as_the_deploy_controller_does(
    guard: float | None, top: float
) -> None:
    core = _core("game_stop", fields=4, options={"command_at": [0.0, 0.0], "speed_guard": guard})
    action, fastest = np.ones((4, 2, core.act_dim)), 0.0
    action[..., 1] = -1.0  # sub-goals in a far corner: the worker drives at its own cap, 2.2 m/s
    for _ in range(40):
        live = core.active.copy()
        core.step(action)
        fastest = max(fastest, np.linalg.norm(core.state.vel[:, :2], axis=-1)[live].max(initial=0.0))
    assert (core.scenario.referee.command == STOP).all()
    assert fastest == pytest.approx(top, abs=1e-9)


def _place(core: HierarchicalCore, pos: np.ndarray, vel: np.ndarray, ball: tuple[float, float]) -> None:
    """Robots of field 0 at ``pos`` (R, 2) moving at ``vel`` (R, 2), facing +x, sub-goals on themselves; the
    ball at rest at ``ball``, where the command found it (not moved: not in play, rules 5.4)."""
    core.world.set_state([0], pos[None], np.zeros((1, len(pos))), vel[None])
    core.world.set_balls([0], np.array([[ball]]))
    core.scenario.ball_at_command[0] = ball
    core.subgoal[0, :, 0:2], core.subgoal[0, :, 2] = pos[:2], 0.0


def test_a_defender_too_close_at_their_free_kick_leaves_for_a_foul_not_a_collision() -> None:
    core = _core("game_free_kick")
    pos = np.array([[0.0, 0.3], [-3.0, -2.0], [3.0, 2.0], [3.0, -2.0]])  # ours 0.3 m from the ball
    _place(core, pos, np.zeros((4, 2)), (0.0, 0.0))
    result = core.step(np.zeros((1, 2, core.act_dim)))
    task = result.info["task"]
    assert task["agent"].tolist() == [0] and result.terminated[0].tolist() == [True, False]
    assert task["foul"][0] == 1.0 and task["collision"][0] == 0.0 and task["success"][0] == 0.0
    counts = {kind: task[f"foul_{kind}"][0] for kind in KINDS}
    assert counts == {kind: float(kind == "defender_too_close") for kind in KINDS}
    assert core.scenario.way[0].tolist() == [FOULED, IN_PLAY]


@pytest.mark.parametrize(("speed", "foul"), [(2.0, True), (0.5, False)])
def test_a_crash_into_an_opponent_is_a_foul_a_slower_contact_a_collision(speed: float, foul: bool) -> None:
    core = _core("game_match", options={"opponent_planner": "random"})
    pos = np.array([[0.0, 3.0], [-4.0, -3.0], [0.185, 3.0], [4.0, -3.0]])
    vel = np.zeros((4, 2))
    vel[0] = [speed, 0.0]
    _place(core, pos, vel, (-3.0, 0.0))
    task = core.step(np.zeros((1, 2, core.act_dim))).info["task"]
    assert task["agent"].tolist() == [0]
    assert (task["foul"][0], task["collision"][0], task["foul_crash_unique"][0]) == (foul, not foul, foul)


def test_stop_comes_at_its_drawn_step_with_new_legal_role_positions() -> None:
    core = _core("game_stop", fields=2, options={"command_at": [0.25, 0.25]})
    scenario = core.scenario
    assert scenario.command_step.tolist() == [10, 10]
    targets = []
    for _ in range(12):
        targets.append(core.target.copy())
        ball = core.world.ball  # where it is when STOP comes at step 10, and how fast it rolls
        assert scenario.referee.command.tolist() == [FORCE_START if core.steps[0] <= 10 else STOP] * 2
        core.step(np.zeros((2, 2, core.act_dim)))
    assert scenario.referee.command.tolist() == [STOP, STOP]
    assert not np.array_equal(targets[10], targets[11])  # the role positions of the ball where it was
    np.testing.assert_array_equal(targets[0], targets[10])
    # Legal for the ball where it comes to rest: at 0.5 m/s^2 from its position and velocity then.
    rest = rest_point(ball.pos[:, 0], ball.vel[:, 0], core.world.ball_spec.deceleration, core.field)
    speed = np.linalg.norm(ball.vel[:, 0], axis=-1)
    np.testing.assert_allclose(np.linalg.norm(rest - ball.pos[:, 0], axis=-1), speed**2 / 1.0, rtol=1e-12)
    zones = forbidden_zones(scenario.referee, rest, core.field, scenario.ours)
    clear = signed_distance(zones, core.target[..., 0:2])
    assert clear.min() >= scenario.options.target_margin - 1e-9


def test_the_observation_carries_the_rules_and_they_read_back() -> None:
    core = _core("game_free_kick", fields=3)
    scenario, obs = core.scenario, core.observe()
    assert obs.shape == (3, 2, core.obs_dim) and core.obs_dim == 13 + 6 * 6 + GAME_OBS_DIM
    columns = obs[..., -GAME_OBS_DIM:]
    flags = columns[..., GAME_OBS_SLICES["referee"]]
    one_hot = np.eye(len(REFEREE_FLAGS))[REFEREE_FLAGS.index("their_free_kick")]
    np.testing.assert_array_equal(flags, np.broadcast_to(one_hot, flags.shape))
    assert (scenario.referee.command == DIRECT_FREE_BLUE).all()
    side = np.where(scenario.referee.blue_on_positive_half, -1.0, 1.0)
    np.testing.assert_array_equal(
        columns[..., GAME_OBS_SLICES["own_goal_side"]][..., 0], side[:, None] * [1, 1]
    )
    ball = core.world.ball.pos[:, 0]
    zones = forbidden_zones(scenario.referee, ball, core.field, scenario.ours)
    max_pos = scenario.scales["max_pos"]
    flat = obs.reshape(6, -1)
    rules = game_rules(flat[:, -GAME_OBS_DIM:], robot_position(flat, max_pos), max_pos)
    np.testing.assert_array_equal(rules.zones.kind, zones.kind.reshape(6, -1))
    used = zones.kind.reshape(6, -1) != 0  # an empty slot's shape and clearance mean nothing
    np.testing.assert_allclose(rules.zones.shape[used], zones.shape.reshape(6, -1, 4)[used], atol=2e-6)
    np.testing.assert_allclose(rules.zones.clearance[used], zones.clearance.reshape(6, -1)[used], atol=1e-6)
    assert used.sum() >= 12  # the walls, the ball for all, each defense area for one robot of each field
    np.testing.assert_array_equal(rules.speed, np.inf)  # a free kick has no speed limit


@pytest.mark.parametrize("flag, limit", [("halt", 0.0), ("stop", 1.5), ("running", np.inf)])
def test_the_speed_limit_reads_back_from_the_referee_flags_exactly(flag: str, limit: float) -> None:
    # Column 7 is the limit / max_v capped at 1 in float32: read back, STOP would be 1.50000006 m/s, and
    # for a robot no faster than 1.5 m/s "no limit". The flags say it exactly.
    columns = np.zeros((1, GAME_OBS_DIM), np.float32)
    columns[0, GAME_OBS_SLICES["referee"].start + REFEREE_FLAGS.index(flag)] = 1.0
    columns[0, GAME_OBS_SLICES["speed_limit"]] = 1.0  # what a robot of max_v <= 1.5 m/s sees in STOP
    assert game_rules(columns, np.zeros((1, 2)), 4.5).speed[0] == limit


def test_a_scripted_planner_plans_under_the_rules_it_reads() -> None:
    core = _core("game_free_kick", fields=2)
    scenario, ball = core.scenario, core.world.ball.pos[:, 0]
    core.target[1, 1, 0:2] = ball[1] + [0.1, 0.0]  # a target the free kick forbids: next to the ball
    obs = core.observe().reshape(4, -1)
    ruled = make_planner("direct", core.config)
    zones = forbidden_zones(scenario.referee, ball, core.field, scenario.ours)
    rules = row_rules(zones, speed_limit(scenario.referee))
    base = obs[:, :-GAME_OBS_DIM]
    np.testing.assert_allclose(ruled(obs), ruled.planner(base, rules=rules), atol=1e-5)
    blind = ruled.planner(base)
    np.testing.assert_allclose(ruled(obs)[:3], blind[:3], atol=1e-6)  # legal targets stay where they are
    assert np.abs(ruled(obs)[3] - blind[3]).max() > 0.01  # the forbidden one is moved out of the zone


def test_game_outcome_on_hand_made_steps() -> None:
    # Four robots: at the target with the command in force; at the target before it; fouled while at the
    # target; a contact. The bonus is 100, the penalty -50.
    reward, success = np.array([[110.0, 110.0, 110.0, -40.0]]), np.array([[True, True, True, False]])
    hit, fouled = np.array([[False, False, False, True]]), np.array([[False, False, True, False]])
    in_force = np.array([[True]])
    out = game_outcome(reward, success, hit, fouled, in_force, 100.0, -50.0)
    np.testing.assert_array_equal(out[0], [[110.0, 110.0, -40.0, -40.0]])
    np.testing.assert_array_equal(out[1], [[True, True, False, False]])
    np.testing.assert_array_equal(out[2], [[False, False, True, True]])
    np.testing.assert_array_equal(out[3], [[SUCCEEDED, SUCCEEDED, FOULED, COLLIDED]])
    later = game_outcome(reward, success, hit, fouled, np.array([[False]]), 100.0, -50.0)
    np.testing.assert_array_equal(later[0], [[10.0, 10.0, -40.0, -40.0]])
    np.testing.assert_array_equal(later[3], [[IN_PLAY, IN_PLAY, FOULED, COLLIDED]])


def test_the_render_shades_the_zones_and_names_the_command(monkeypatch: pytest.MonkeyPatch) -> None:
    env = hier_ssl.scenario_env("game_ball_placement", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    frame = env.render()
    monkeypatch.setattr(type(env.core.scenario), "extra_render", Scenario.extra_render)
    assert (frame != env.render()).any(axis=-1).mean() > 0.01


def test_evaluation_reports_fouls_by_kind() -> None:
    # Full size (6 v 6): at the opponent's free kick `direct` drives one robot too close to the ball.
    config = scenario_config("game_free_kick", frame_skip=8)
    result = evaluate(make_planner("direct", config), config, episodes=2, seed=0)
    assert set(result["fouls"]) == set(KINDS) and result["fouls"]["defender_too_close"] >= 1
    assert result["foul_rate"] > 0.0
    per = result["per_robot"]
    assert not (per["foul"] & per["collision"]).any()
    assert result["foul_rate"] == per["foul"].mean()
    # Fouls per robot-minute: over the time each robot played, 25 ms a control step.
    assert result["robot_minutes"] == pytest.approx(per["length"].sum() * 0.025 / 60)
    for kind, count in result["fouls"].items():
        assert result["fouls_per_robot_minute"][kind] * result["robot_minutes"] == pytest.approx(count)
    record = make_record("direct", result)
    table = markdown_table([record])
    assert table.splitlines()[0].endswith("| Foul |") and "fouls of direct: " in table
    assert f"per robot-minute ({result['robot_minutes']:.1f} played): all " in table
    header, row = csv_table([record]).splitlines()
    values = dict(zip(header.split(","), row.split(","), strict=True))
    for kind, rate in result["fouls_per_robot_minute"].items():
        assert float(values[f"fouls_per_robot_minute_{kind}"]) == rate


def test_the_observation_of_some_fields_is_theirs_in_the_observation_of_all() -> None:
    core = _core("game_ball_placement", fields=3)
    core.step(np.zeros((3, 2, core.act_dim)))
    np.testing.assert_array_equal(core.observe(np.array([2, 0])), core.observe()[[2, 0]])
    referee = core.scenario.referee.fields([2, 0])
    np.testing.assert_array_equal(referee.placement, core.scenario.referee.placement[[2, 0]])


def test_a_recorded_game_episode_draws_the_ball_and_the_referee_as_they_were() -> None:
    config = scenario_config("game_stop", **{**SMALL, "options": {"command_at": [0.25, 0.25]}})
    core = HierarchicalCore(config, 1, autoreset=False)
    episode = play(core, make_planner("direct", config), 0, record=[0])["trajectories"][0]
    steps = len(episode["robots"])
    assert (
        episode["ssl_teams"] and episode["balls"].shape == (steps, 1, 2) and len(episode["drawings"]) == steps
    )
    commands = [int(d.keywords["referee"].command[0]) for d in episode["drawings"]]
    assert commands[:11] == [FORCE_START] * 11 and set(commands[11:]) == {STOP}  # STOP at step 10
    assert not np.array_equal(episode["balls"][0], episode["balls"][-1])  # the ball rolled
    episode["outcome"], episode["cpad"] = ["timeout"] * 2, [0.0] * 2
    drawn = _panel(core.field, episode)
    bare = _panel(core.field, {k: v for k, v in episode.items() if k not in ("balls", "drawings")})
    assert (drawn != bare).any(axis=-1).mean() > 0.01  # the zones, the ball and the command's name


def test_a_fouled_robot_is_labelled_a_foul_in_figures() -> None:
    result = {"trajectories": [{"field": 0}]}
    no = np.zeros((1, 3), bool)
    label_outcomes(
        result, no, np.array([[False, True, False]]), np.zeros((1, 3)), np.array([[True, False, False]])
    )
    episode = result["trajectories"][0]
    assert episode["outcome"] == ["foul", "collision", "timeout"]
    episode["robots"] = np.zeros((5, 3, 2))
    assert panel_title("direct", episode) == "direct\n0/3 reached, 1 collided (robot 1), 1 fouled, 4 steps"


def test_half_the_defenders_at_a_free_kick_mark_an_attacker_goal_side() -> None:
    scenario = make_scenario(scenario_config("game_free_kick"))
    placement = scenario.reset_world_at(100, np.random.default_rng(0))
    target, theirs = placement.target[:, 1:, 0:2], placement.pos[:, 6:]  # robot 0 is the keeper
    gaps = np.linalg.norm(target[:, :, None] - theirs[:, None], axis=-1)
    marking = np.abs(gaps - MARK_DISTANCE).min(axis=-1) < 1e-9  # left where the mark put it
    assert 0.3 < marking.mean() < 0.5  # of the half drawn, the marks that no zone or robot moved
    our_goal = np.where(placement.blue_on_positive_half, -1.0, 1.0) * scenario.field.half_length
    marked = np.take_along_axis(theirs, np.abs(gaps - MARK_DISTANCE).argmin(axis=-1)[..., None], axis=1)
    nearer = np.abs(target[..., 0] - our_goal[:, None]) < np.abs(marked[..., 0] - our_goal[:, None])
    assert nearer[marking].all()


def test_no_defender_too_close_once_the_free_kicks_ball_has_moved() -> None:
    # Rules 5.4: the opponents' "ball" robots push the ball; once it has moved 5 cm from where it lay when
    # the free kick came (at the reset) it is in play, and a defender near it commits no foul.
    settings = {"num_agents": 6, "num_obstacles": 6, "max_steps": 300, "frame_skip": 1}
    core = HierarchicalCore(scenario_config("game_free_kick", **settings), 16, autoreset=False)
    planner = make_planner("direct", core.config)
    obs = core.reset(seed=0)
    at_command = core.world.ball.pos[:, 0].copy()
    moved = np.zeros(core.num_fields, bool)  # in play stays in play: the ball rolling back changes nothing
    action, close, fouls = np.zeros(core.active.shape + (core.act_dim,)), KINDS.index("defender_too_close"), 0
    while core.active.any():
        action[core.active] = planner(obs[core.active])
        before = core.scenario.fouls[..., close].sum(axis=1)
        obs = core.step(action).obs
        moved |= np.linalg.norm(core.world.ball.pos[:, 0] - at_command, axis=-1) >= IN_PLAY_DISTANCE
        called = core.scenario.fouls[..., close].sum(axis=1) - before
        assert not (called & moved).any(), np.flatnonzero(called & moved)
        np.testing.assert_array_equal(core.scenario.referee.in_play, moved)
        fouls += called.sum()
    assert moved.any() and fouls > 0  # the ball moves, and a defender too close before it did is fouled


def _crossings(start: np.ndarray, end: np.ndarray) -> int:
    """How many pairs of the straight paths start -> end (F, M, 2) cross, over every field."""
    d = end - start
    rel = start[:, None] - start[:, :, None]  # (F, i, j): from robot i's start to robot j's

    def side(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    # j's ends either side of i's path, and i's ends either side of j's.
    j_ends = side(d[:, :, None], rel) * side(d[:, :, None], rel + d[:, None])
    i_ends = side(d[:, None], -rel) * side(d[:, None], -rel + d[:, :, None])
    crossing = (j_ends < 0) & (i_ends < 0)
    return int(np.triu(crossing, k=1).sum())


def test_assign_roles_finds_the_least_total_distance_keeper_fixed() -> None:
    rng = np.random.default_rng(1)
    pos, target = rng.uniform(-3, 3, (40, 5, 2)), rng.uniform(-3, 3, (40, 5, 5))
    out = assign_roles(pos, target, keeper=2)
    np.testing.assert_array_equal(out[:, 2], target[:, 2])
    for f in range(40):  # every ordering of the other four, by brute force
        orders = [p for p in itertools.permutations(range(5)) if p[2] == 2]
        costs = [np.linalg.norm(pos[f] - target[f, list(p), :2], axis=-1).sum() for p in orders]
        assert np.linalg.norm(pos[f] - out[f, :, :2], axis=-1).sum() == pytest.approx(min(costs), abs=1e-12)
        assert sorted(map(tuple, out[f])) == sorted(map(tuple, target[f]))


def test_a_team_assignment_hands_out_the_drawn_positions_with_no_paths_crossing() -> None:
    drawn = make_scenario(scenario_config("game_ball_placement")).reset_world_at(50, np.random.default_rng(0))
    team_config = scenario_config("game_ball_placement", options={"assign": "team"})
    team = make_scenario(team_config).reset_world_at(50, np.random.default_rng(0))
    np.testing.assert_array_equal(team.pos, drawn.pos)  # the same draws: only who goes where differs
    np.testing.assert_array_equal(team.target[:, 0], drawn.target[:, 0])  # the keeper keeps its own
    ours = drawn.pos[:, :6]
    assert _crossings(ours[:, 1:], drawn.target[:, 1:, :2]) > 50
    assert _crossings(ours[:, 1:], team.target[:, 1:, :2]) == 0
    np.testing.assert_array_equal(np.sort(team.target, axis=1), np.sort(drawn.target, axis=1))


def test_stops_role_positions_are_assigned_from_where_the_robots_are_when_it_comes() -> None:
    settings = {
        "num_agents": 6,
        "num_obstacles": 6,
        "options": {"command_at": [0.25, 0.25], "assign": "team"},
    }
    core = _core("game_stop", fields=8, **settings)
    for _ in range(10):  # STOP comes at step 10, its positions handed out from where the robots stand
        core.step(np.zeros((8, 6, core.act_dim)))
    at_command, before = core.world.state.pos[:, 1:6].copy(), core.target.copy()
    core.step(np.zeros((8, 6, core.act_dim)))
    assert (core.scenario.referee.command == STOP).all() and not np.array_equal(core.target, before)
    assert _crossings(at_command, core.target[:, 1:, :2]) == 0

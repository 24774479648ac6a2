"""A pick that starts an episode flies straight to its pre-grasp point unless that line (or the drop the drone makes
before it moves across) takes it into the scene; then it follows a planned route from where it is. PackageDelivery's
street has starts behind a counter's 45 cm upstand, with the hanging fingers below its top edge: flown straight, 7 of
100 chains (seed 0) ended in a collision within the first second (docs/expert.md)."""

import gymnasium as gym
import torch

import aerobench.envs  # noqa: F401
from aerobench.expert import ExpertController
from aerobench.expert.pick import START_RISE_M, PickExpert, PickPhase

ENV0 = torch.tensor([0])
BEHIND_THE_UPSTAND = 5  # plan index of `eval --setting PackageDelivery --chain pick,transport,place --seed 0`
IN_THE_OPEN = 0


def _deliver_chain(episode: int):
    env = gym.make("AeroSequential-v1", obs_mode="state_dict", setting="PackageDelivery", chain="deliver")
    env.reset(seed=episode, options={"reconfigure": True})  # seed 0: episode i runs with seed i
    controller = ExpertController(env.unwrapped)
    controller.reset(ENV0)
    pick = controller.experts[0]
    assert isinstance(pick, PickExpert) and not pick.after_stage
    return env, controller, pick


def test_a_start_with_a_clear_line_flies_straight():
    env, _, pick = _deliver_chain(IN_THE_OPEN)
    assert int(pick.phase[0]) == PickPhase.APPROACH and not pick.routed
    env.close()


def test_a_start_behind_the_upstand_routes_over_it_and_picks_without_touching_the_scene():
    env, controller, pick = _deliver_chain(BEHIND_THE_UPSTAND)
    assert int(pick.phase[0]) == PickPhase.ROUTE
    waypoints = pick.route.points[0, : int(pick.route.length[0])]
    start = env.unwrapped.agent.airframe_state().position[0]
    assert torch.allclose(waypoints[0], start + torch.tensor([0.0, 0.0, START_RISE_M]), atol=1e-5)  # climbs first, no backing off
    assert float(waypoints[1:, 2].max()) > float(start[2]) + 0.1  # climbs over the upstand
    worst = 0.0
    for _ in range(400):  # the chained protocol's pick budget
        _, _, terminated, truncated, info = env.step(controller.act())
        worst = max(worst, float(info["nontarget_contact_force"][0]))
        if int(info["subtask_index"][0]) > 0 or terminated[0] or truncated[0]:
            break
    assert int(info["subtask_index"][0]) == 1, "the pick stage did not finish"
    assert worst < 1.0, f"the drone touched the scene ({worst:.1f} N)"
    env.close()

"""The articulation expert inserts from wherever its tool centre point stands in the insertion corridor: between the
standoff point and the handle, on the handle's normal, facing it, slow. Where a policy it labels (DAgger) flew on past
the standoff point, the label is "insert from here", not "back out to the standoff point and stop first"."""

import math
from types import SimpleNamespace

import torch

from aerobench.expert.articulation import CORRIDOR_M, CORRIDOR_SPEED_MPS, STANDOFF_M, ArticulationExpert

POINT = torch.tensor([[1.0, 2.0, 1.2]])
NORMAL = torch.tensor([[-1.0, 0.0, 0.0]])  # the handle faces -x: a drone facing it has yaw 0
FACING = torch.zeros(1)


def in_corridor(out: float, side: float = 0.0, yaw: float = 0.0, speed: float = 0.0) -> bool:
    tcp = POINT + out * NORMAL + torch.tensor([[0.0, side, 0.0]])
    state = SimpleNamespace(yaw=torch.tensor([yaw]), velocity=torch.tensor([[speed, 0.0, 0.0]]))
    return bool(ArticulationExpert._in_corridor(tcp, POINT, NORMAL, FACING, state)[0])


def test_between_the_standoff_point_and_the_handle_facing_it_and_slow_is_the_corridor():
    assert in_corridor(0.08) and in_corridor(STANDOFF_M) and in_corridor(0.01, side=CORRIDOR_M * 0.8)
    assert not in_corridor(STANDOFF_M + 2 * CORRIDOR_M)  # still short of the standoff point: the approach goes on
    assert not in_corridor(0.08, side=1.5 * CORRIDOR_M)  # off the normal: the fingers would meet the bar
    assert not in_corridor(-0.03)  # beyond the handle
    assert not in_corridor(0.08, yaw=math.radians(15))  # not facing it
    assert not in_corridor(0.08, speed=CORRIDOR_SPEED_MPS + 0.05)  # too fast to insert from

"""The radar's mounting on the robot (radarodom.mount): parsed from x,y,z,yaw_deg, refused with the reason."""

from __future__ import annotations

import math

import pytest

from radarodom.errors import UsageError
from radarodom.mount import Mount, parse_mount


def test_a_mount_is_read_in_metres_and_degrees():
    m = parse_mount("0.3,-0.05,0.42,90")
    assert (m.x, m.y, m.z) == (0.3, -0.05, 0.42)
    assert m.yaw == pytest.approx(math.pi / 2)
    assert m.lever_arm_m == pytest.approx(math.hypot(0.3, 0.05))
    assert not m.is_identity and Mount().is_identity and parse_mount("0,0,0,0").is_identity


@pytest.mark.parametrize("text", ["0.3,0,0", "0.3,0,0,0,0", "a,0,0,0", "nan,0,0,0", "0,inf,0,0", "1_0,0,0,0",
                                  "0x1,0,0,0", "", "1e999,0,0,0", "500,0,0,0"])
def test_a_bad_mount_is_one_usage_error_saying_what(text):
    with pytest.raises(UsageError, match="mount"):
        parse_mount(text)


def test_a_mount_of_non_numbers_is_refused():
    with pytest.raises(UsageError, match="finite"):
        Mount(float("nan"))

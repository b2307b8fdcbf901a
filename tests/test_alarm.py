"""The test alarms: the CPU clock trips on a spinning hang and ignores a blocked wait."""

import time

import pytest

from .alarm import alarm


class Tripped(Exception):
    pass


def test_cpu_alarm_trips_on_spinning_and_not_on_sleeping():
    with pytest.raises(Tripped, match="CPU"):
        with alarm(0.05, Tripped, clock="cpu"):
            while True:
                pass
    with alarm(0.05, Tripped, clock="cpu"):
        time.sleep(0.2)                  # wall time passes, CPU time does not


def test_wall_alarm_trips_on_sleeping():
    with pytest.raises(Tripped, match="0.05 s: a hang"):
        with alarm(0.05, Tripped):
            time.sleep(5)

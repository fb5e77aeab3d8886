"""The timer's alarms at the microsecond they match (`timer_alarm.py`),
beside rp2040py's own arming, which fires up to a microsecond early.

    firmware/pico-sim/.venv/bin/python -m pytest firmware/pico-sim/test_timer_alarm.py
"""

import random

from rp2040py.rp2040 import RP2040
from rp2040py.simulator import Simulator
from rp2040py.utils.logging import ConsoleLogger, LogLevel

from timer_alarm import install, nanos_until

TIMER = 0x4005_4000
ALARM0, TIMERAWL = TIMER + 0x10, TIMER + 0x28


def chip(fixed):
    """A chip whose alarm 0's firings are recorded: (simulated ns, the
    count the firmware would read then)."""
    mcu = RP2040()
    mcu.logger = ConsoleLogger(LogLevel.ERROR)
    sim = Simulator(rp2040=mcu)
    if fixed:
        install(mcu)
    fired = []
    fire = mcu.timer._fire_alarm

    def record(index):
        fired.append((sim.clock.nanos, mcu.read_uint32(TIMERAWL)))
        fire(index)

    mcu.timer._fire_alarm = record
    return mcu, sim.clock, fired


def arm_at(mcu, clock, now_ns, value):
    """At simulated `now_ns`, arms alarm 0 for count `value`."""
    clock.tick(now_ns - clock.nanos)
    mcu.write_uint32(ALARM0, value)


def test_rp2040py_alone_fires_before_the_count_comes():
    # 12.6 µs in, armed for 15: rp2040py arms it int(2.4) = 2 µs ahead.
    mcu, clock, fired = chip(fixed=False)
    arm_at(mcu, clock, 12_600, 15)
    clock.tick(10_000)
    assert fired == [(14_600, 14)]


def test_an_alarm_fires_when_the_count_reaches_its_value():
    mcu, clock, fired = chip(fixed=True)
    arm_at(mcu, clock, 12_600, 15)
    clock.tick(10_000)
    assert fired == [(15_000, 15)]
    # Armed on a microsecond's first nanosecond, and for the count now.
    arm_at(mcu, clock, 30_000, 31)
    clock.tick(5_000)
    assert fired[-1] == (31_000, 31)
    arm_at(mcu, clock, 40_250, 40)
    clock.tick(1)
    assert fired[-1] == (40_250, 40)


def test_the_wait_is_to_the_next_match_for_any_value_and_fraction():
    rng = random.Random(7)
    for _ in range(10_000):
        now_ns = rng.randrange(0, 1 << 50)
        whole = now_ns // 1000
        ahead = rng.choice([0, 1, 2, rng.randrange(1, 1 << 32)])
        value = (whole + ahead) & 0xFFFF_FFFF
        wait = nanos_until(value, now_ns)
        if ahead == 0:
            assert wait == 0
        else:
            # The count then is the value, and was not a nanosecond before.
            assert (now_ns + wait) // 1000 == whole + ahead
            assert (now_ns + wait - 1) // 1000 < whole + ahead

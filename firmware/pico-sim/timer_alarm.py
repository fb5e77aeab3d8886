"""The timer's alarms fire at the microsecond they match, as on the chip.

The RP2040's timer counts microseconds, and an alarm fires when the low
32 bits of the count equal its value (RP2040 data sheet 4.6). rp2040py
0.3.6 arms an alarm `int(value - now)` microseconds ahead, `now` with its
fraction: armed 1.4 µs before its microsecond it fires 1 µs later, 0.4 µs
before that microsecond begins. A firmware that checks the count when
its alarm fires (the Pico's edge interrupt does: an edge goes out only
once its CT has come) then finds it not yet come, arms the alarm again,
`int(0.4)` = 0 ahead, fires at once, and so on until the count turns:
its interrupt re-entered for up to a microsecond at every edge, a cost
the chip does not have (four axes at 20,000 steps/s make 160,000 edges a
second), and an edge driven either just after its microsecond began or
an interrupt's entry later, by chance.

`install(mcu)` arms each alarm for the moment the count reaches its
value: the next such moment, up to 2^32 µs ahead, or at once for the
count now (as rp2040py does; the chip would wait for the count to come
round, and a firmware that arms an alarm for a count it may have reached
checks the count after arming).
"""

import math

from rp2040py.peripherals import timer as rp_timer

#: The alarm registers' offsets.
ALARMS = {rp_timer.ALARM0: 0, rp_timer.ALARM1: 1, rp_timer.ALARM2: 2, rp_timer.ALARM3: 3}


def nanos_until(value, now_ns):
    """Simulated ns from `now_ns` (the timer's count in ns since its
    epoch) until the count's low 32 bits first equal `value`; 0 when they
    do now."""
    whole = math.floor(now_ns / 1000)
    ahead = (value - whole) & 0xFFFF_FFFF
    if ahead == 0:
        return 0
    return math.ceil((whole + ahead) * 1000 - now_ns)


def install(mcu):
    timer = mcu.timer
    write = timer.write_uint32

    def write_uint32(offset, value):
        index = ALARMS.get(offset)
        if index is None:
            write(offset, value)
            return
        alarm = timer.alarms[index]
        alarm.armed = True
        alarm.target_micros = value
        now_ns = timer.clock.nanos - timer._epoch_nanos
        alarm.clock_alarm.schedule(nanos_until(value, now_ns))

    timer.write_uint32 = write_uint32

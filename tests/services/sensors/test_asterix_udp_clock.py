"""An ASTERIX UDP feed read without --date: each record's day comes from the receive
clock (the day nearest its arrival), and records far from the receive clock (an old
capture) are warned about once."""

from __future__ import annotations

import datetime as dt
import logging

from skyfuse.schemas import PlotBatch
from skyfuse.services.asterix import AsterixStreamDecoder
from skyfuse.services.asterix.writer import AsterixPlotWriter
from skyfuse.services.sensors.asterix_udp import AsterixUdpSensor
from skyfuse.services.sensors.config import SensorServiceConfig


def ns(*args) -> int:
    return int(dt.datetime(*args, tzinfo=dt.UTC).timestamp()) * 10**9


def sector(t_ns: int) -> PlotBatch:
    return PlotBatch(
        radar_id="7-1", scan=0, seq=0, time_start=t_ns - 10**9, time_end=t_ns, time=[t_ns],
        range=[50_000.0], azimuth=[0.3], mode_s=[0xA1B2C3],
    )  # fmt: skip


def decoded_times(recv_ns: int) -> list[int]:
    data = AsterixPlotWriter({}, simulated=False).encode([sector(ns(2026, 1, 1, 0, 10))])
    dec = AsterixStreamDecoder(date=None)
    batches = dec.feed(data, recv_ns) + dec.flush()
    return [t for b in batches for t in b.time]


def test_day_of_the_record_is_taken_from_the_receive_clock():
    # time of day 00:10:00, received 10 minutes later on another day: that day
    assert decoded_times(ns(2026, 3, 5, 0, 20)) == [ns(2026, 3, 5, 0, 10)]
    # received at 23:55 the evening before: the nearest 00:10 is 15 minutes ahead
    assert decoded_times(ns(2026, 3, 4, 23, 55)) == [ns(2026, 3, 5, 0, 10)]


def test_records_far_from_the_receive_clock_are_warned_about_once(caplog):
    sensor = AsterixUdpSensor.__new__(AsterixUdpSensor)  # no socket, no session
    sensor.cfg = SensorServiceConfig(asterix_udp="127.0.0.1:30048")
    sensor._clock_warned = False
    now = ns(2026, 3, 5, 3, 0)
    with caplog.at_level(logging.WARNING):
        sensor._check_clock([sector(now + 60 * 10**9)], now)  # a minute: fine
        assert not caplog.records
        sensor._check_clock([sector(now + 5 * 3600 * 10**9)], now)
        sensor._check_clock([sector(now + 5 * 3600 * 10**9)], now)
    assert len(caplog.records) == 1
    msg = caplog.records[0].getMessage()
    assert "5.0 h ahead of" in msg and "--date" in msg

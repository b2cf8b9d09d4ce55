"""A recording's times are the traffic log's, to the microsecond: the same rounding as ``datetime``'s.

The log writes ``datetime.fromtimestamp(t).isoformat(timespec="microseconds")``;
``record``'s MCAP log times and CSV ``t`` column come from ``sinks.seconds``.
Rounding ``t * 1e6`` put one live time in eight a microsecond off the log's.
"""

from __future__ import annotations

from datetime import datetime, timezone

from helpers_mcap import us_of
from hypothesis import given
from hypothesis import strategies as st

from hcrctl.recording.sinks import microseconds, seconds

#: Epoch seconds from now to a century on, and any float from 0 to there.
TIMES = st.floats(1.7e9, 4.9e9) | st.floats(0, 4.9e9)


def log_microseconds(t: float) -> int:
    """What the traffic log's time says, in whole microseconds: ``datetime``'s own rounding."""
    return us_of(datetime.fromtimestamp(t, timezone.utc))


@given(TIMES)
def test_microseconds_round_as_the_logs_time_does(t: float) -> None:
    assert microseconds(t) == log_microseconds(t)


@given(TIMES)
def test_the_seconds_text_is_the_logs_time(t: float) -> None:
    us, text = seconds(t)
    stamp = datetime.fromtimestamp(t, timezone.utc).isoformat(timespec="microseconds")
    whole, _, fraction = text.partition(".")
    assert us == log_microseconds(t)
    assert datetime.fromtimestamp(int(whole), timezone.utc).strftime("%Y-%m-%dT%H:%M:%S") == stamp[:19]
    assert fraction == stamp[20:26]


def test_a_time_that_rounding_the_product_got_wrong() -> None:
    """A live time where ``round(t * 1e6)`` says ...724 and the log says ...723."""
    t = 1795661489.7887235
    assert round(t * 1e6) != log_microseconds(t)  # the old way: a microsecond off
    assert microseconds(t) == log_microseconds(t) == 1795661489788723

"""Per-sender admission of cmd_vel (``fleet.shed``): a flood spends its own budget, never a driver's.

The clock is the test's: nothing waits and nothing is timed.
"""

from __future__ import annotations

from hcrctl.fleet.shed import MAX_BUDGETS, SESSION_BURST, STRANGER_BURST, STRANGER_RATE, Shed, sender
from hcrctl.link.zenoh import keyspace

DRIVER = keyspace.Who("driver", "0123456789abcdef")
OTHER = keyspace.Who("other", "fedcba9876543210")


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def attachment(who: keyspace.Who, seq: int) -> bytes:
    return f"{who.name} {who.session} {seq} {'ab' * 64}".encode()


def shed_of(*present: keyspace.Who) -> tuple[Shed, Clock]:
    clock = Clock()
    return Shed(lambda who: who in present, clock=clock), clock


def test_a_flood_of_strangers_is_shed_past_its_budget_and_the_driver_still_read() -> None:
    shed, clock = shed_of(DRIVER)
    garbage = [shed.admits(b"\xfe\xff garbage") for _ in range(10 * int(STRANGER_BURST))]
    names = [shed.admits(f"evil{n} {n:016x} {n}".encode()) for n in range(1000)]
    assert sum(garbage) == STRANGER_BURST and not any(names)
    assert shed.shed == len(garbage) + len(names) - STRANGER_BURST
    assert all(shed.admits(attachment(DRIVER, seq)) for seq in range(int(SESSION_BURST)))
    clock.now += 1.0  # a second later the strangers have a second's worth again
    assert sum(shed.admits(None) for _ in range(10 * int(STRANGER_RATE))) == min(
        STRANGER_RATE, STRANGER_BURST
    )


def test_a_copy_of_a_present_sessions_name_spends_that_sessions_budget_only() -> None:
    shed, _ = shed_of(DRIVER, OTHER)
    copies = [shed.admits(attachment(DRIVER, 1)) for _ in range(10 * int(SESSION_BURST))]
    assert sum(copies) == SESSION_BURST
    assert all(shed.admits(attachment(OTHER, seq)) for seq in range(int(SESSION_BURST)))
    assert sum(shed.admits(b"nobody") for _ in range(int(STRANGER_BURST))) == STRANGER_BURST


def test_the_sender_is_the_first_two_fields_and_nothing_else_is_read() -> None:
    assert sender(attachment(DRIVER, 7)) == DRIVER
    assert sender(b"driver 0123456789abcdef 7") == DRIVER
    assert sender(b"one-field") is None
    assert sender(b"\xff\xfe x y") is None
    assert sender(None) is None


def test_budgets_are_kept_for_the_most_recently_heard_sessions_only() -> None:
    """MAX_BUDGETS sessions' budgets at most: the least recently heard is forgotten first (and starts full),
    while one heard since keeps its spent budget."""
    first, second, *others = [keyspace.Who(f"op{n}", f"{n:016x}") for n in range(MAX_BUDGETS + 1)]
    shed = Shed(lambda who: True, clock=Clock())
    for who in (first, second):
        assert sum(shed.admits(attachment(who, 1)) for _ in range(2 * int(SESSION_BURST))) == SESSION_BURST
    for who in others[:-1]:  # the budgets kept are full now
        assert shed.admits(attachment(who, 1))
    assert not shed.admits(attachment(second, 2))  # heard again: spent still, and now the most recent
    assert shed.admits(attachment(others[-1], 1))  # one more session: the least recently heard is forgotten
    assert shed.admits(attachment(first, 2)), "the least recently heard session's budget was kept"
    assert not shed.admits(attachment(second, 3)), "a session heard since lost its spent budget"

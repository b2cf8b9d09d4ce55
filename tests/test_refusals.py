"""The refusal budget and the serial queries' turns, with the test's own clock (no time asserted)."""

from __future__ import annotations

import threading
import time

from helpers import wait_until

from hcrctl.fleet.queries import Turnstile
from hcrctl.served.refusals import MAX_LINES, Refusals


def test_refusals_beyond_the_budget_are_one_line_with_their_count() -> None:
    clock, said = [0.0], []
    refusals = Refusals(lambda op, text, seq: said.append((op, text)), clock=lambda: clock[0])
    for n in range(100):  # alternating names: each one new
        refusals.refused(f"evil{n}", "refused: op1 drives r1")
    assert said == [(f"evil{n}", "refused: op1 drives r1") for n in range(MAX_LINES)]
    refusals.tick()
    assert len(said) == MAX_LINES  # the window is not over yet
    clock[0] = 1.5
    refusals.tick()
    assert said[-1] == (None, f"... and {100 - MAX_LINES} more refusals in the last 1.5 s")
    refusals.refused("evil7", "refused: op1 drives r1")  # a new window: said again
    assert said[-1] == ("evil7", "refused: op1 drives r1")


def test_the_same_refusal_again_is_not_said_again_but_counted() -> None:
    clock, said = [0.0], []
    refusals = Refusals(lambda op, text, seq: said.append((op, text)), clock=lambda: clock[0])
    for _ in range(10):
        refusals.refused("op2", "refused: op1 drives r1")
    assert said == [("op2", "refused: op1 drives r1")]
    clock[0] = 1.0
    refusals.tick()
    assert said[-1] == (None, "... and 9 more refusals in the last 1.0 s")


def test_a_serial_query_waits_for_a_sweep_after_the_last_one_left() -> None:
    """Queries take turns with the poller: the second waits until a sweep ends after the first left."""
    paused, swept, asked = threading.Event(), [0.0], []

    def last_sweep() -> float:
        asked.append(threading.current_thread())
        return swept[0]

    turns = Turnstile(paused, last_sweep, wait=30.0)
    with turns():
        assert paused.is_set()
    assert not paused.is_set()
    entered = threading.Event()

    def second() -> None:
        with turns():
            entered.set()

    thread = threading.Thread(target=second)
    thread.start()
    # the second query has looked at the last sweep twice (so found it old and waited), or went in
    wait_until(lambda: entered.is_set() or asked.count(thread) >= 2, what="the second query waiting or in")
    assert not entered.is_set()  # no sweep since the first query left
    swept[0] = time.monotonic()  # the poller's sweep
    assert entered.wait(30.0)
    thread.join()


def test_a_flood_of_fake_names_crowds_out_no_sessions_words_and_is_bounded() -> None:
    """100,000 refusals under names with no token share one budget: the driver and another session present
    are still told, each on a budget of its own, and the words remembered stay few."""
    clock, said = [0.0], []
    present = {"op1", "op2"}
    refusals = Refusals(
        lambda op, text, seq: said.append((op, text)), known=present.__contains__, clock=lambda: clock[0]
    )
    for n in range(100_000):
        refusals.refused(f"fake{n}", "refused: op1 drives r1")
    refusals.refused("op1", "cmd_vel refused: forward blocked", 7)
    refusals.refused("op2", "refused: op1 drives r1")
    assert said[-2:] == [("op1", "cmd_vel refused: forward blocked"), ("op2", "refused: op1 drives r1")]
    assert len(said) == MAX_LINES + 2 and refusals.remembered == MAX_LINES + 2
    assert not refusals.may_say()  # the others' budget is spent: their attachments need not be read
    clock[0] = 1.0
    refusals.tick()
    assert said[-1] == (None, f"... and {100_000 - MAX_LINES} more refusals in the last 1.0 s")
    assert refusals.remembered == 0


def test_a_sessions_own_budget_is_its_own() -> None:
    """A session present that floods uses up its own budget only: another session is still told."""
    clock, said = [0.0], []
    refusals = Refusals(
        lambda op, text, seq: said.append((op, text)),
        known={"op1", "op2"}.__contains__,
        clock=lambda: clock[0],
    )
    for n in range(1000):
        refusals.refused("op2", f"cmd_vel refused: kind {chr(65 + n % 26)}")
    refusals.refused("op1", "cmd_vel refused: forward blocked")
    assert [op for op, _ in said].count("op2") == MAX_LINES and said[-1][0] == "op1"

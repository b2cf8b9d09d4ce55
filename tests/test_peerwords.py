"""The one budget for words about peers (``served.peerwords``), with the test's own clock (no time asserted)."""

from __future__ import annotations

from hcrctl.served.notes import Level
from hcrctl.served.peerwords import MAX_BUDGETS, MAX_LINES, PeerWords


class Said:
    """A ``Note`` that keeps what it was told."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, Level]] = []

    def __call__(self, text: str, level: Level = Level.INFO) -> None:
        self.lines.append((text, level))

    @property
    def texts(self) -> list[str]:
        return [text for text, _ in self.lines]


def words_with_clock(known: set[str] | None = None) -> tuple[PeerWords, Said, list[float]]:
    clock, said = [0.0], Said()
    words = PeerWords(said, clock=lambda: clock[0])
    if known is not None:
        words.know(known.__contains__)
    return words, said, clock


def test_words_beyond_the_budget_are_one_line_with_their_count() -> None:
    words, said, clock = words_with_clock()
    for n in range(100):  # alternating names: each one new
        words.say(f"evil{n}", "refused: op1 drives r1")
    assert said.texts == ["refused: op1 drives r1"] * MAX_LINES
    words.tick()
    assert len(said.lines) == MAX_LINES  # the window is not over yet
    clock[0] = 1.5
    words.tick()
    assert said.lines[-1] == (f"... and {100 - MAX_LINES} more refusals in the last 1.5 s", Level.WARN)
    words.say("evil7", "refused: op1 drives r1")  # a new window: said again
    assert said.texts[-1] == "refused: op1 drives r1" and len(said.lines) == MAX_LINES + 2


def test_the_same_word_again_is_not_said_again_but_counted() -> None:
    words, said, clock = words_with_clock()
    for seq in range(10):
        words.say("op2", f"ignored cmd_vel {seq}: replayed")  # a kind is its text without the numbers
    assert said.texts == ["ignored cmd_vel 0: replayed"]
    clock[0] = 1.0
    words.tick()
    assert said.texts[-1] == "... and 9 more refusals in the last 1.0 s"


def test_a_flood_of_fake_names_crowds_out_no_sessions_words_and_is_bounded() -> None:
    """100,000 words under names with no budget of their own share one: the driver and another session
    known are still told, each on a budget of its own, and the words remembered stay few."""
    words, said, clock = words_with_clock({"op1", "op2"})
    for n in range(100_000):
        words.say(f"fake{n}", "refused: op1 drives r1")
    assert words.allowed("op1", "cmd_vel refused: forward blocked")
    assert words.allowed("op2", "refused: op1 drives r1")
    assert len(said.lines) == MAX_LINES and words.remembered == MAX_LINES + 2
    assert not words.may_say()  # the others' budget is spent: their attachments need not be read
    clock[0] = 1.0
    words.tick()
    assert said.texts[-1] == f"... and {100_000 - MAX_LINES} more refusals in the last 1.0 s"
    assert words.remembered == 0


def test_a_known_senders_own_budget_is_its_own() -> None:
    """A session known that floods uses up its own budget only: another session is still told."""
    words, _, _ = words_with_clock({"op1", "op2"})
    told = [n for n in range(1000) if words.allowed("op2", f"cmd_vel refused: kind {chr(65 + n % 26)}")]
    assert len(told) == MAX_LINES
    assert words.allowed("op1", "cmd_vel refused: forward blocked")
    assert words.allowed(None, "ignored a cmd_vel without a valid attachment")  # the others' budget too


def test_every_front_ends_senders_draw_on_the_one_budget() -> None:
    """A ROS 2 writer, a bridge client and a fleet name with no token are all others: together they are
    told ``MAX_LINES`` words a window, not ``MAX_LINES`` each (the fleet, ROS 2 and the bridge side by side)."""
    words, said, clock = words_with_clock({"op1"})
    for n in range(1000):
        words.say(("ros2 writer", n), "cmd_vel from a writer refused: busy", kind="busy")
        words.say(("client", n), "client advertised /cmd_vel in cbor", kind="cbor")
        words.say(f"fake{n}", "refused: op1 drives r1")
    assert len(said.lines) == MAX_LINES
    clock[0] = 1.0
    words.tick()
    assert said.texts[-1] == f"... and {3000 - MAX_LINES} more refusals in the last 1.0 s"


def test_the_count_goes_to_every_channel_once() -> None:
    """The count line is said on stderr (whose copies are ``/rosout``) once, and on each channel added."""
    words, said, clock = words_with_clock()
    status: list[str] = []
    words.count_to(status.append)
    for n in range(MAX_LINES + 3):
        words.say(f"evil{n}", "refused: op1 drives r1")
    clock[0] = 1.0
    words.tick()
    words.tick()
    count = "... and 3 more refusals in the last 1.0 s"
    assert said.texts.count(count) == 1 and status == [count]


def test_flush_says_what_was_held_back_before_the_window_ends() -> None:
    """At the end of a run (the server closing), what the open window held back is said, not lost."""
    words, said, clock = words_with_clock()
    for _ in range(4):
        words.say("client 1", "client 1 advertised /cmd_vel in cbor", kind="cbor")
    clock[0] = 0.25
    words.flush()
    assert said.texts == ["client 1 advertised /cmd_vel in cbor", "... and 3 more refusals in the last 0.2 s"]
    words.flush()
    assert len(said.lines) == 2  # nothing held back since


def test_known_senders_with_budgets_of_their_own_are_bounded() -> None:
    """However many senders a front end knows, the budgets of their own in a window are at most
    ``MAX_BUDGETS``; beyond them a known sender shares the others' budget, so memory stays bounded."""
    words, _, _ = words_with_clock()
    words.know(lambda sender: True)
    told = sum(words.allowed(f"op{n}", "refused: op1 drives r1") for n in range(3 * MAX_BUDGETS))
    assert told == MAX_BUDGETS + MAX_LINES  # one word each for those with a budget, the others' budget's
    assert words.remembered == MAX_BUDGETS + MAX_LINES


def test_one_budget_is_made_per_serving_process_and_no_module_counts_words_of_its_own() -> None:
    """Every front end and channel speaks through the runtime's one ``PeerWords``: none makes another, and
    no other module says a count of what it held back (as the bridge and each front end once did)."""
    from helpers_source import modules_matching

    assert modules_matching(r"\bPeerWords\(") == {"served/runtime.py"}
    assert modules_matching(r"more (refusals )?in ") == {"served/peerwords.py"}


def test_a_ros2_writer_refused_in_words_that_hold_an_age_is_told_once_a_window() -> None:
    """A stale bumper reading's refusal names its age, new with every Twist: the words without their
    numbers are its kind, so a writer refused a thousand times in a window is told once, the rest counted."""
    from types import SimpleNamespace

    from hcrctl.motion.governor import Verdict
    from hcrctl.ros2.drive import RosCmdVel

    class Stale:
        """A governor whose bumper reading is always too old for forward motion."""

        driver = None

        def would_refuse(self, source: object) -> None:
            return None

        def offer(self, source: object, wheels: object) -> Verdict:
            self.age = getattr(self, "age", 500) + 1
            return Verdict(False, f"refused: bumper reading stale ({self.age} ms old, over 500 ms)")

    words, said, clock = words_with_clock()
    cmd_vel = RosCmdVel(Stale(), said, words)  # type: ignore[arg-type]
    axes = {"x": 0.0, "y": 0.0, "z": 0.0}
    twist = SimpleNamespace(linear=SimpleNamespace(**{**axes, "x": 0.1}), angular=SimpleNamespace(**axes))
    for _ in range(1000):
        cmd_vel.message("6343720887c9286", twist)
    assert cmd_vel.refused == 1000
    assert said.texts == [
        "cmd_vel from ROS 2 writer 6343720887c9286 refused: bumper reading stale (501 ms old, over 500 ms)"
    ]
    clock[0] = 1.0
    words.tick()
    assert said.texts[-1] == "... and 999 more refusals in the last 1.0 s"

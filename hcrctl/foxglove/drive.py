"""The bridge's ``/cmd_vel``: which client channels carry it, and each message read and offered.

This is a *source* of motion, nothing more: it runs on the server's thread,
reads each message on a budget (``cmdvel.parse_twist``) and offers the wheels
to the motion governor, which alone decides, writes and stops. A client that
does not drive is refused, its payload read only to find a zero Twist (from
anyone, a stop that holds: ``governor.HOLD_RULE``) on the budget every
message is read on, so a second client cannot make the driver's messages
cost much more. Whatever happens to a message is
returned as text for the client's ``status`` (``None``: taken). A client
keeps at most ``MAX_CHANNELS`` ``/cmd_vel`` channels. What a client does
that is worth a line on stderr (an advertise refused or read differently, a
Twist that is no Twist) is said on the serving process's one budget for
words about peers (``served.peerwords``), not once per message.
"""

from __future__ import annotations

from ..motion.governor import STILL, Governor, Kind, Source
from ..served.cmdvel import SCHEMA_NAMES, TOPIC, BadTwist, parse_twist, twist_wheels
from ..served.notes import Level, Note
from ..served.peerwords import PeerWords
from ..served.untrusted import shown

#: (client id, client channel id)
Publisher = tuple[int, int]
#: ``/cmd_vel`` channels one client may hold: one drives; more only cost memory.
MAX_CHANNELS = 8


def client_source(client: int) -> Source:
    """A client as the governor knows it; said as ``client N`` to the terminal and to the other clients."""
    return Source(Kind.CLIENT, client, f"client {client}")


class CmdVelSource:
    """Client channels advertised as ``/cmd_vel``, their messages turned into offers to ``governor``."""

    def __init__(self, governor: Governor, note: Note, words: PeerWords) -> None:
        self.governor = governor
        self._note = note
        self._words = words
        self._channels: set[Publisher] = set()
        self._per_client: dict[int, int] = {}

    def advertised(
        self, client: int, channel: int, topic: str, encoding: str, schema_name: str
    ) -> str | None:
        """A client channel: kept if it is ``/cmd_vel`` in JSON; what to tell the client otherwise."""
        if topic != TOPIC:
            return None
        if encoding != "json":
            self._words.say(
                client_source(client),
                f"{client_source(client)} advertised {TOPIC} in {shown(encoding)}: only json is accepted",
                Level.INFO,
                kind="advertised in an encoding other than json",
            )
            return f"{TOPIC} is accepted in json only, not {shown(encoding)}"
        if (client, channel) not in self._channels and self._per_client.get(client, 0) >= MAX_CHANNELS:
            return f"{TOPIC} refused: at most {MAX_CHANNELS} {TOPIC} channels per client"
        if schema_name not in SCHEMA_NAMES:
            self._words.say(
                client_source(client),
                f"{client_source(client)} advertised {TOPIC} as {shown(schema_name)}; reading it as a Twist",
                Level.INFO,
                kind="advertised with another schema",
            )
        if (client, channel) not in self._channels:
            self._channels.add((client, channel))
            self._per_client[client] = self._per_client.get(client, 0) + 1
        return None

    def unadvertised(self, client: int, channel: int) -> None:
        if (client, channel) in self._channels:
            self._channels.discard((client, channel))
            if (held := self._per_client.pop(client, 1) - 1) > 0:
                self._per_client[client] = held
            self.governor.release(client_source(client), f"{client_source(client)} left {TOPIC}")

    def gone(self, client: int) -> None:
        """The client disconnected: each of its channels is unadvertised."""
        for publisher in [p for p in self._channels if p[0] == client]:
            self.unadvertised(*publisher)

    def data(self, client: int, channel: int, payload: bytes) -> str | None:
        """One message: offered to the governor; why not, for the client's status."""
        if (client, channel) not in self._channels:
            return None  # not /cmd_vel: nothing else is read
        source = client_source(client)
        driver, refused = self.governor.driver, self.governor.would_refuse(source)
        try:
            wheels = twist_wheels(*parse_twist(payload))
        except BadTwist as exc:
            if refused is not None:
                return f"{TOPIC} {refused}"
            self._words.say(source, f"{source}: {TOPIC} refused: {exc}", Level.WARN, kind="not a Twist")
            return f"{TOPIC} refused: {exc}"
        if refused is not None and wheels != STILL:  # a zero from anyone is a stop, never refused
            return f"{TOPIC} {refused}"
        verdict = self.governor.offer(source, wheels)
        if verdict.taken and driver != source == self.governor.driver:
            self._note(f"{source} drives the robot ({TOPIC})")
        return None if verdict.taken else f"{TOPIC} {verdict.why}"

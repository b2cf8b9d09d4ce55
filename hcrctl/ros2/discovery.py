"""Where the node looks for peers: ROS 2's discovery settings, honoured on Cyclone DDS as rmw_cyclonedds does.

ROS 2 (Iron and later) says how far a node discovers others with
``ROS_AUTOMATIC_DISCOVERY_RANGE`` and ``ROS_STATIC_PEERS`` (addresses
separated by ``;``); the older ``ROS_LOCALHOST_ONLY=1`` still wins over both.
rmw_cyclonedds turns them into a Cyclone DDS configuration fragment put
before the user's ``CYCLONEDDS_URI`` (the fragments are merged in order, so
what the user's file sets is what holds):

``LOCALHOST``
    no multicast at all, the participant found by unicast at ``localhost``
    (and the static peers), and the loopback interface as Cyclone's own:
    nothing is announced off this machine, and a localhost-only node on
    another middleware finds this one. (rmw_cyclonedds keeps Cyclone's
    choice of interface; a Fast DDS node that is localhost-only then cannot
    reach the addresses it announces, measured here, so this one names
    loopback; with static peers, which may be other hosts, Cyclone chooses
    as rmw_cyclonedds lets it.)
``SUBNET`` (the default, and an empty value)
    Cyclone's own multicast discovery, plus the static peers.
``OFF``
    no multicast, no participant index, and a discovery tag of this
    process's own: no other participant discovers this one.
``SYSTEM_DEFAULT``
    Cyclone's own settings, untouched (static peers ignored).

Another value is taken as ``LOCALHOST``, with a warning, as rcl does. The
node says each warning once on stderr (and ``/rosout``).

Standard library only: the rules are data and text, the DDS side applies them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from xml.sax.saxutils import quoteattr

RANGE_ENV = "ROS_AUTOMATIC_DISCOVERY_RANGE"
PEERS_ENV = "ROS_STATIC_PEERS"
LOCALHOST_ONLY_ENV = "ROS_LOCALHOST_ONLY"
OFF, LOCALHOST, SUBNET, SYSTEM_DEFAULT = "OFF", "LOCALHOST", "SUBNET", "SYSTEM_DEFAULT"
RANGES = (OFF, LOCALHOST, SUBNET, SYSTEM_DEFAULT)
#: What an unset or empty range is (rcl's default from Jazzy).
DEFAULT_RANGE = SUBNET
#: The longest peer address rmw takes (``RMW_DISCOVERY_OPTIONS_STATIC_PEERS_MAX_LENGTH``).
PEER_CHARS = 256
#: The loopback interface, by its address (its name differs between systems: lo, lo0).
LOOPBACK = '<Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>'
#: Participants found on one host by their index (rmw_cyclonedds': roughly, ROS 2 processes on the host).
MAX_PARTICIPANT_INDEX = 32


@dataclass(frozen=True)
class Discovery:
    """The range, the static peers that count, and what was wrong with the settings (one line each)."""

    range: str
    peers: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()


def from_environ(environ: Mapping[str, str]) -> Discovery:
    """The discovery settings ``environ`` gives, as rcl reads them."""
    warnings: list[str] = []
    peers = _peers(environ.get(PEERS_ENV, ""), warnings)
    if environ.get(LOCALHOST_ONLY_ENV, "") == "1":
        if peers:
            warnings.append(
                f"{LOCALHOST_ONLY_ENV}=1: {PEERS_ENV} ignored (deprecated setting, still honoured)"
            )
        return Discovery(LOCALHOST, (), tuple(warnings))
    asked = environ.get(RANGE_ENV, "")
    found = asked or DEFAULT_RANGE
    if found not in RANGES:
        warnings.append(
            f"{RANGE_ENV}={asked[:PEER_CHARS]!r} is not one of {', '.join(RANGES)}: localhost only"
        )
        found = LOCALHOST
    if peers and found in (OFF, SYSTEM_DEFAULT):
        warnings.append(f"{RANGE_ENV}={found}: {PEERS_ENV} ignored")
        peers = ()
    return Discovery(found, peers, tuple(warnings))


def _peers(value: str, warnings: list[str]) -> tuple[str, ...]:
    peers = []
    for peer in (p.strip() for p in value.split(";")):
        if len(peer) > PEER_CHARS:
            warnings.append(f"a {PEERS_ENV} address longer than {PEER_CHARS} characters ignored")
        elif peer:
            peers.append(peer)
    return tuple(peers)


def cyclone_fragment(discovery: Discovery, pid: int) -> str:
    """The Cyclone DDS configuration that applies ``discovery`` ('' for ``SYSTEM_DEFAULT``: Cyclone's own)."""
    if discovery.range == SYSTEM_DEFAULT:
        return ""
    general = {
        OFF: "<General><AllowMulticast>false</AllowMulticast></General>",
        LOCALHOST: f"<General>{'' if discovery.peers else LOOPBACK}<AllowMulticast>false</AllowMulticast></General>",
    }.get(discovery.range, "")
    if discovery.range == OFF:
        finding = f"<ParticipantIndex>none</ParticipantIndex><Tag>ros_discovery_off_{pid}</Tag>"
    else:
        peers = (["localhost"] if discovery.range == LOCALHOST else []) + list(discovery.peers)
        listed = "".join(f"<Peer address={quoteattr(p)}/>" for p in peers)
        finding = (
            "<ParticipantIndex>auto</ParticipantIndex>"
            f"<MaxAutoParticipantIndex>{MAX_PARTICIPANT_INDEX}</MaxAutoParticipantIndex>"
            + (f"<Peers>{listed}</Peers>" if listed else "")
        )
    return f"<CycloneDDS><Domain>{general}<Discovery>{finding}</Discovery></Domain></CycloneDDS>"


def cyclone_config(environ: Mapping[str, str], pid: int) -> tuple[str | None, tuple[str, ...]]:
    """The configuration a Cyclone DDS domain is made with (None: Cyclone reads ``CYCLONEDDS_URI`` itself)
    and the warnings: the discovery fragment first, then the user's ``CYCLONEDDS_URI``, whose settings win."""
    discovery = from_environ(environ)
    fragment = cyclone_fragment(discovery, pid)
    if not fragment:
        return None, discovery.warnings
    user = environ.get("CYCLONEDDS_URI", "")
    return (f"{fragment},{user}" if user else fragment), discovery.warnings

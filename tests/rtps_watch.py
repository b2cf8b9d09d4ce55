"""Every RTPS packet of one DDS vendor on this host's interfaces, a line each: ``IFACE SRC > DST``.

Run as root (a packet socket sees every interface, both ways), on the host
under test (``ip netns exec NS python rtps_watch.py VENDOR``); prints
``ready`` once it listens, then one line per IPv4 UDP datagram whose payload
is an RTPS message from ``VENDOR`` (the RTPS header's vendor id, hex: Eclipse
Cyclone DDS is ``0110``, eProsima Fast DDS ``010f``). Standard library only:
it imports nothing of hcrctl's, so what it reports is what went on the wire.
"""

from __future__ import annotations

import socket
import struct
import sys

#: Every protocol: a packet socket of one protocol sees only what comes in, not what this host sends.
ETH_P_ALL = 0x0003
ETH_P_IP = 0x0800
ETH_HEADER = 14
UDP = 17
#: The RTPS header: the magic, the version (2 bytes), then the vendor id (2 bytes).
MAGIC = b"RTPS"


def datagram(frame: bytes) -> tuple[str, str, bytes] | None:
    """(source, destination, payload) of an IPv4 UDP frame, else None."""
    if frame[12:14] != ETH_P_IP.to_bytes(2, "big"):
        return None
    ip = frame[ETH_HEADER:]
    if len(ip) < 20 or ip[0] >> 4 != 4 or ip[9] != UDP:
        return None
    header = (ip[0] & 0x0F) * 4
    sport, dport = struct.unpack("!HH", ip[header : header + 4])
    src, dst = socket.inet_ntoa(ip[12:16]), socket.inet_ntoa(ip[16:20])
    return f"{src}:{sport}", f"{dst}:{dport}", ip[header + 8 :]


def main() -> None:
    vendor = bytes.fromhex(sys.argv[1])
    sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
    print("ready", flush=True)
    while True:
        frame, where = sock.recvfrom(65535)
        found = datagram(frame)
        if found is not None and found[2][:4] == MAGIC and found[2][6:8] == vendor:
            print(f"{where[0]} {found[0]} > {found[1]}", flush=True)


if __name__ == "__main__":
    main()

"""Hints that are true: an RFC 2217 server that stops short in the negotiation (ser2net in telnet
mode) is named with ``?ign_set_control``, and a global option placed after the subcommand says
it is global and where it goes.

The telnet server here is a real TCP server speaking the telnet option and RFC 2217
sub-negotiation bytes, as ser2net does; hcrctl connects to it through pyserial's rfc2217://.
"""

from __future__ import annotations

import shlex
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

import click
import pytest
from helpers_cli import one_line
from helpers_hex import run

from hcrctl.cli import cli
from hcrctl.protocol.frames import encode

IAC, DONT, DO, WONT, WILL, SB, SE = 255, 254, 253, 252, 251, 250, 240
COM_PORT_OPTION = 44
SET_CONTROL = 5
#: Telnet options the server agrees to: binary, echo, suppress-go-ahead.
PLAIN_TELNET = frozenset({0, 1, 3})


class TelnetServer:
    """ser2net in telnet mode: ``rfc2217`` on, it confirms every setting except flow control
    (it answers SET_CONTROL with another value, as ser2net and sredird do); off, it refuses
    the COM-port option and ignores its requests. No serial data ever comes back."""

    def __init__(self, rfc2217: bool) -> None:
        self.rfc2217 = rfc2217
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self._threads = [threading.Thread(target=self._accept, daemon=True)]
        self._threads[0].start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            thread = threading.Thread(target=self._talk, args=(conn,), daemon=True)
            self._threads.append(thread)
            thread.start()

    def _talk(self, conn: socket.socket) -> None:
        buf = bytearray()
        with conn:
            while data := _recv(conn):
                buf += data
                with suppress(OSError):
                    self._answer(conn, buf)

    def _answer(self, conn: socket.socket, buf: bytearray) -> None:
        """Answer every whole telnet command in ``buf``; leave a partial one there."""
        while (at := buf.find(IAC)) >= 0 and len(buf) >= at + 3:
            verb, option = buf[at + 1], buf[at + 2]
            if verb == SB:
                end = buf.find(bytes((IAC, SE)), at)
                if end < 0:
                    break
                body = bytes(buf[at + 2 : end])
                del buf[: end + 2]
                if body[0] == COM_PORT_OPTION and self.rfc2217:
                    command, value = body[1], body[2:]
                    if command == SET_CONTROL:
                        value = bytes((value[0] ^ 0x80,))
                    conn.sendall(bytes((IAC, SB, COM_PORT_OPTION, command + 100)) + value + bytes((IAC, SE)))
                continue
            del buf[: at + 3]
            agreed = option in PLAIN_TELNET or (option == COM_PORT_OPTION and self.rfc2217)
            if verb == WILL:
                conn.sendall(bytes((IAC, DO if agreed else DONT, option)))
            elif verb == DO:
                conn.sendall(bytes((IAC, WILL if agreed else WONT, option)))
        if buf.find(IAC) < 0:
            buf.clear()  # data bytes: nobody reads them

    def close(self) -> None:
        self.sock.close()


def _recv(conn: socket.socket) -> bytes:
    try:
        return conn.recv(4096)
    except OSError:
        return b""


@contextmanager
def telnet_server(rfc2217: bool) -> Iterator[TelnetServer]:
    server = TelnetServer(rfc2217)
    try:
        yield server
    finally:
        server.close()


def read_compass(url: str) -> tuple[int, str]:
    proc = run("--port", url, "--timeout", "0.2", "--retries", "0", "read", "compass", timeout=60)
    return proc.returncode, one_line(proc.stderr)


def test_a_server_that_will_not_confirm_flow_control_is_named_with_ign_set_control() -> None:
    with telnet_server(rfc2217=True) as server:
        url = f"rfc2217://127.0.0.1:{server.port}"
        code, line = read_compass(url)
        fixed_code, fixed_line = read_compass(f"{url}?ign_set_control")
    assert code == 1, line  # the server's failure, not a malformed --port (exit 2)
    assert line.startswith("hcrctl: error: RFC 2217 negotiation failed: the server did not confirm the flow")
    assert f"(hint: add ?ign_set_control: --port '{url}?ign_set_control')" in line
    # the hint is true: with the option, the port opens, and only the (absent) robot is missing
    assert fixed_code == 1 and "no reply to compass" in fixed_line, fixed_line


def test_a_plain_telnet_server_is_told_apart_and_the_hint_keeps_the_urls_options() -> None:
    with telnet_server(rfc2217=False) as server:
        url = f"rfc2217://127.0.0.1:{server.port}?timeout=0.5"
        code, line = read_compass(url)
    assert code == 1, line
    assert "RFC 2217 negotiation failed: the server did not confirm the baud rate" in line
    assert "telnet(rfc2217)" in line and "socket://HOST:PORT" in line
    assert f"--port '{url}&ign_set_control'" in line


def test_a_malformed_rfc2217_url_is_still_a_usage_error() -> None:
    proc = run("--port", "rfc2217://127.0.0.1:1?bogus", "read", "compass")
    assert proc.returncode == 2
    assert "unknown option" in one_line(proc.stderr)


# -- global options after the subcommand ---------------------------------------------------------------

#: A valid value for each global option that takes one; the test below fails for a new global
#: option until it has one here, so every option stays covered.
SAMPLES = {
    "--port": "sim://",
    "--baud": "9600",
    "--address": "0x01",
    "--timeout": "0.3",
    "--retries": "1",
    "--checksum-from": "address",
    "--log": "LOGFILE",
    "--protocol": "v0.15",
    "--stop-wait": "5",
    "--deadman": "0.8",
    "--zenoh": "tcp/127.0.0.1:7447",
    "--zenoh-config": "ZENOHCONFIG",
}
FRAME = encode(0x01, 0x14, b"\x04\xd2").hex(" ").split()


def global_options() -> list[click.Option]:
    return [p for p in cli.params if isinstance(p, click.Option)]


def test_every_global_option_that_takes_a_value_has_a_sample() -> None:
    takes_value = {p.opts[0] for p in global_options() if not p.is_flag}
    assert takes_value == set(SAMPLES)


@pytest.mark.parametrize("option", [p.opts[0] for p in global_options()])
def test_a_global_option_after_the_subcommand_says_where_it_goes(option: str, tmp_path: object) -> None:
    zenoh_config = Path(str(tmp_path), "zenoh.json5")
    zenoh_config.write_text("{}\n")
    sample = SAMPLES.get(option, "").replace("LOGFILE", f"{tmp_path}/log.jsonl")
    value = [sample.replace("ZENOHCONFIG", str(zenoh_config))] if option in SAMPLES else []
    proc = run("read", "compass", option, *value)
    assert proc.returncode == 2 and proc.stdout == ""
    line = one_line(proc.stderr)
    fixed = ["hcrctl", option, *value, "read", "compass"]
    assert line == (
        f"hcrctl read: error: {option} is a global option: put it before the subcommand: "
        f"{shlex.join(fixed)} (see 'hcrctl read --help')"
    )
    corrected = run(*fixed[1:])  # and the line it shows is right
    assert corrected.returncode in (0, 1), corrected.stderr
    assert "no such option" not in corrected.stderr.lower()


def test_the_issues_example_and_the_short_and_equals_forms() -> None:
    line = one_line(run("hex", "decode", "--checksum-from", "address", *FRAME).stderr)
    assert "--checksum-from is a global option: put it before the subcommand: " in line
    assert f"hcrctl --checksum-from address hex decode {' '.join(FRAME)}" in line
    line = one_line(run("--json", "read", "-psim://", "--timeout=0.3", "compass").stderr)
    assert "-p is a global option: put it before the subcommand: hcrctl --json -psim:// read" in line


def test_a_misspelled_option_is_still_no_such_option() -> None:
    proc = run("hex", "decode", "--chcksum-from", "address", *FRAME)
    assert proc.returncode == 2
    line = one_line(proc.stderr)
    assert "No such option" in line and "global" not in line

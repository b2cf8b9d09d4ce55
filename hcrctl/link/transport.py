"""Opening ports: any pyserial URL or device path, plus our own ``sim://``.

Every way opening can fail becomes one ``PortError`` with a hint, so the CLI
can print one line instead of pyserial's nested exception text.
"""

from __future__ import annotations

import errno
import os

import serial

from ..errors import BadPortUrl, PortBusy, PortError
from .defaults import BAUD
from .transport_sim import register as register_sim

SIM_HINT = "use --port sim:// for the built-in simulator"
SIM_OPTIONS_HINT = "for example sim://?drop=0.1&seed=3; docs/simulator.md lists every option"
BUSY_HINT = "another program has it open; close it and retry (hcrctl stop still works: it asks that program)"
URL_HINT = "a device path, or a URL such as socket://HOST:PORT, rfc2217://HOST:PORT, loop:// or sim://"


def open_port(url: str, baud: int = BAUD, timeout: float | None = 0.1) -> serial.SerialBase:
    """Open ``url`` for the client; raises PortError with a hint on any failure."""
    register_sim()
    is_device = "://" not in url
    try:
        return serial.serial_for_url(url, baudrate=baud, timeout=timeout, exclusive=is_device or None)
    except (OSError, ValueError, KeyError, TypeError) as exc:  # pyserial raises all four
        raise _open_error(url, exc) from exc


def _open_error(url: str, exc: Exception) -> PortError:
    """A wrong URL is a usage error (exit 2); anything else is the port's failure (exit 1)."""
    if url.startswith("sim://") and isinstance(exc, OSError):  # the simulator fails only on its options
        return BadPortUrl(url, str(exc).removeprefix("bad sim:// option: "), hint=SIM_OPTIONS_HINT)
    refused = _rfc2217_error(url, str(exc)) if url.startswith("rfc2217://") else None
    if refused is not None:
        return refused
    problem = _url_problem(exc) if "://" in url else None
    if problem is not None:
        return BadPortUrl(url, problem, hint=URL_HINT)
    if isinstance(exc, OSError):
        return _port_error(url, exc)
    return PortError(f"cannot open: {exc}", url, hint=SIM_HINT)


RAW_TCP = "for a raw TCP port use socket://HOST:PORT"


def _rfc2217_error(url: str, text: str) -> PortError | None:
    """An RFC 2217 negotiation that stopped short, named with the URL option that gets past it.

    pyserial reports a server's refusal as a ValueError, which would read as a
    bad URL. ser2net in telnet mode never confirms the flow-control setting,
    which is what ``?ign_set_control`` tells pyserial not to wait for; a hint
    never suggests the option when the URL has it already.
    """
    ign = (
        ""
        if "ign_set_control" in url
        else f"add ?ign_set_control: --port '{with_option(url, 'ign_set_control')}'"
    )
    if "option 'control'" in text:  # rejected, or never answered
        what, hint = "the server did not confirm the flow-control setting (ser2net does not)", ign
    elif "does not seem to support RFC2217" in text:
        what = "the server does not speak RFC 2217 (plain telnet or raw TCP)"
        enable = "for ser2net enable RFC 2217 (telnet(rfc2217) in ser2net.yaml, remctl in ser2net.conf)"
        hint = f"{enable}{' and ' + ign if ign else ''}; {RAW_TCP}"
    elif "does not accept parameter change" in text:
        what = "the server did not confirm the baud rate and framing"
        enabled = "is RFC 2217 enabled on the server (ser2net: telnet(rfc2217))?"
        hint = f"{enabled}{' then ' + ign if ign else ''}; {RAW_TCP}"
    elif "waiting for option" in text:  # 'purge' and the like: some ser2net versions never answer
        what = "the server did not answer an RFC 2217 request"
        hint = f"{ign + '; ' if ign else ''}or serve the port raw: {RAW_TCP}"
    else:
        return None
    return PortError(f"RFC 2217 negotiation failed: {what}", url, hint=hint or None)


def with_option(url: str, option: str) -> str:
    """``url`` with one more query option."""
    return f"{url}{'&' if '?' in url else '?'}{option}"


def _url_problem(exc: BaseException) -> str | None:
    """Why pyserial refused a URL's text, or None when the URL was not the problem.

    pyserial's parsers report a bad URL as a ValueError, which some handlers
    wrap in a SerialException or trip over into a KeyError or TypeError; the
    innermost ValueError of the chain says what was wrong.
    """
    chain: list[BaseException] = []
    link: BaseException | None = exc
    while link is not None and len(chain) < 8:
        chain.append(link)
        link = link.__context__
    reasons = [str(e) for e in chain if isinstance(e, ValueError)]
    if reasons:
        return reasons[-1]
    return "malformed URL" if any(isinstance(e, (KeyError, TypeError)) for e in chain) else None


def _port_error(url: str, exc: Exception) -> PortError:
    """Classify an open failure by errno first, then by pyserial's wording."""
    code = getattr(exc, "errno", None)
    text = str(exc)
    if code == errno.ENOENT or "No such file" in text:
        return PortError("no such port", url, hint=ports_hint())
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return PortError(
            "permission denied",
            url,
            hint="add yourself to the dialout group (sudo usermod -aG dialout $USER) and log in again",
        )
    if code == errno.EBUSY or "busy" in text or "exclusively lock" in text:
        return PortBusy("the port is busy", url, hint=BUSY_HINT)
    if any(
        words in text for words in ("Name or service not known", "nodename nor servname", "name resolution")
    ):
        return PortError("unknown host", url, hint="check the host name in the URL")
    if code == errno.ECONNREFUSED or "refused" in text:
        return PortError(
            "connection refused", url, hint="is the server (for example hcrctl sim --tcp) running?"
        )
    text = text.removeprefix(f"Could not open port {url}: ")  # we name the port ourselves
    return PortError(f"cannot open ({text})", url, hint=SIM_HINT)


def ports_hint() -> str:
    """The serial ports present, for error hints."""
    from serial.tools import list_ports

    found = sorted(p.device for p in list_ports.comports())
    listed = ", ".join(found) if found else "none found"
    return f"ports present: {listed}; {SIM_HINT}"


def describe(port: serial.SerialBase | str) -> str:
    """The name to show for a port in messages."""
    if isinstance(port, str):
        return port
    return str(getattr(port, "portstr", None) or getattr(port, "port", None) or os.fspath("?"))

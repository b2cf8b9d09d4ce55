"""Build an Arduino sketch into an ELF the emulated chip runs, as the Arduino IDE would.

A sketch (``.pde``, ``.ino``) is C++ with three things the IDE adds: an
``#include <Arduino.h>``, prototypes of the sketch's own functions (plain
avr-g++ wants a function declared before its use), and the Arduino core
linked in. Old sketches also use the Arduino 0022 API, so two shims are
defined: ``BYTE=0`` gives ``Serial.print(x, BYTE)`` its old meaning (print
the raw byte: ``Print::print(n, 0)`` does), and ``DECIMAL_DIG`` is defined
for the core's ``WString.cpp`` with Debian's avr-libc. A built ``.elf`` is
used as is; an Intel ``.hex`` is turned into a raw flash image.

Builds are cached (``toolchain.cached``), keyed by the sketch, the MCU, the
clock, the flags and the compiler's version. A failed build is one line: the
compiler's first error and the path of the full log. The build is bounded in
memory, CPU and wall time (``toolchain.run_bounded``), the sketch's file name
is written into the generated source as a C string (``c_string``: a name is
never code), and a built file is checked before the chip gets it
(``image``). Standard library only.
"""

from __future__ import annotations

import os
import re
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO

from ...errors import HcrError
from . import toolchain
from .image import MAX_FILE_BYTES, check_elf, hex_image, refused

SKETCH_SUFFIXES = (".pde", ".ino")
BUILT_SUFFIXES = (".elf", ".hex")
#: Bump when the way a sketch is built changes, so old cache entries are not reused.
RECIPE = "1"
#: The Arduino 1.8 IDE's flags (platform.txt), without LTO, plus the old-API shims.
_COMMON = ("-Os", "-w", "-ffunction-sections", "-fdata-sections", "-DARDUINO=10807", "-DARDUINO_ARCH_AVR")
_SHIMS = ("-DBYTE=0", "-DDECIMAL_DIG=17")
_CXX = ("-std=gnu++11", "-fpermissive", "-fno-exceptions", "-fno-threadsafe-statics")
_C = ("-std=gnu11",)
_LOG = "build.log"


def firmware_image(path: Path, mcu: str, clock: int, say: Callable[[str], None] = lambda _line: None) -> Path:
    """What the harness loads for ``path``: an ELF (built and cached for a sketch) or a raw ``.bin``.

    ``say`` hears a line before a build that is not cached yet (it takes a few seconds).
    """
    suffix = path.suffix.lower()
    data = read_firmware(path)
    if suffix == ".elf":  # the harness loads the bytes checked here, a copy: not the file, which may change
        check_elf(path.name, data, mcu)
        key = toolchain.digest("elf", data)
        return toolchain.cached("firmware", key, "firmware.elf", _writing("firmware.elf", data))
    if suffix == ".hex":
        image = hex_image(path.name, data, mcu)
        key = toolchain.digest("hex", image)
        return toolchain.cached("firmware", key, "firmware.bin", _writing("firmware.bin", image))
    toolchain.require(toolchain.BUILD_NEEDS)
    key = toolchain.digest(RECIPE, data, path.name, mcu, str(clock), _compiler_version())

    def build(out: Path) -> None:
        say(f"building {path.name} for {mcu} at {clock} Hz (cached for the next start)")
        _build(path, data, mcu, clock, out)

    return toolchain.cached("firmware", key, "firmware.elf", build)


def read_firmware(path: Path) -> bytes:
    """The file's bytes, or the one line saying why it cannot be read (more than ``MAX_FILE_BYTES`` included)."""
    try:
        with path.open("rb") as handle:
            data = handle.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise HcrError(f"cannot read the firmware {path}: {exc.strerror or exc}") from None
    if len(data) > MAX_FILE_BYTES:
        raise refused(path.name, f"it is larger than {MAX_FILE_BYTES >> 20} MiB, more than any firmware file")
    return data


def _compiler_version() -> str:
    try:
        return subprocess.run(["avr-g++", "--version"], capture_output=True, text=True, check=False).stdout
    except OSError:
        return ""


def _build(path: Path, data: bytes, mcu: str, clock: int, out: Path) -> None:
    """Compile the core and the sketch (C, C++ and assembly at once), then link ``firmware.elf``."""
    core = toolchain.ARDUINO_AVR / "cores" / "arduino"
    flags = [
        f"-mmcu={mcu}",
        f"-DF_CPU={clock}L",
        *_COMMON,
        *_SHIMS,
        f"-I{core}",
        f"-I{toolchain.ARDUINO_AVR / 'variants' / 'standard'}",
    ]
    sketch = out / "sketch.cpp"
    sketch.write_bytes(sketch_source(data, path.name))
    log = out / _LOG
    deadline = time.monotonic() + toolchain.BUILD_TIMEOUT_S
    with log.open("wb") as sink:
        steps = [
            ["avr-gcc", "-c", *flags, *_C, *map(str, sorted(core.glob("*.c")))],
            ["avr-g++", "-c", *flags, *_CXX, *map(str, sorted(core.glob("*.cpp"))), str(sketch)],
            ["avr-gcc", "-c", *flags, "-x", "assembler-with-cpp", *map(str, sorted(core.glob("*.S")))],
        ]
        _check_steps(path, log, _run(path, log, steps, out, sink, deadline))
        objects = sorted(str(p) for p in out.glob("*.o"))
        link = ["avr-g++", f"-mmcu={mcu}", "-Os", "-Wl,--gc-sections", *objects, "-o", "firmware.elf", "-lm"]
        _check_steps(path, log, _run(path, log, [link], out, sink, deadline))
    for obj in objects:
        Path(obj).unlink()


def _run(
    path: Path, log: Path, steps: list[list[str]], out: Path, sink: IO[bytes], deadline: float
) -> list[int]:
    """``toolchain.run_bounded``, a build that ran out of time said as a failed build."""
    try:
        return toolchain.run_bounded(steps, out, sink, deadline)
    except toolchain.BuildBounded as exc:
        raise _failed(path, log, exc.message) from None


def _check_steps(path: Path, log: Path, statuses: list[int]) -> None:
    """Every step ended well, or the build failed: a bound a step met, else the compiler's first error."""
    if all(status == 0 for status in statuses):
        return
    bound = next((b for b in map(toolchain.bound_met, statuses) if b is not None), None)
    raise _failed(path, log, bound)


#: A log line that says why a build failed: the compiler's errors, and running out of memory at its bound.
_FAILURE = re.compile(r"error|out of memory|memory exhausted", re.IGNORECASE)


def _failed(path: Path, log: Path, bound: str | None = None) -> HcrError:
    """The compiler's first error (or the bound a step met) as one line, and where the whole log is."""
    if bound is None:
        text = log.read_text(errors="replace")
        first = next((ln.strip() for ln in text.splitlines() if _FAILURE.search(ln)), "the build failed")
        if "memory" not in first.lower():  # the compiler's own error in the sketch
            return HcrError(f"cannot build {path.name}: {first}", hint=f"the full log is {log}")
        bound = first  # out of memory: at its address-space bound
    return HcrError(
        f"cannot build {path.name}: {bound}",
        hint=f"a build is bounded to {toolchain.BOUNDS}; the full log is {log}",
    )


def _writing(product: str, data: bytes) -> Callable[[Path], None]:
    """A cache entry's maker that writes ``data`` as ``product``."""

    def write(folder: Path) -> None:
        (folder / product).write_bytes(data)

    return write


# -- what the Arduino IDE adds to a sketch ------------------------------------------------

_COMMENT_OR_STRING = re.compile(rb"//[^\n]*|/\*.*?\*/|\"(?:\\.|[^\"\\\n])*\"|'(?:\\.|[^'\\\n])*'", re.S)
_DIRECTIVE = re.compile(rb"^[ \t]*#[^\n]*(?:\\\n[^\n]*)*", re.M)
_HEAD = re.compile(rb"^[A-Za-z_][\w\s\*&:<>,]*?[\s\*&]([A-Za-z_]\w*)\s*\([^;{}()=]*\)\s*$")
_NOT_FUNCTIONS = {b"if", b"for", b"while", b"switch", b"return", b"sizeof"}


def sketch_source(data: bytes, name: str) -> bytes:
    """The C++ file avr-g++ compiles: Arduino.h, the sketch's prototypes, then the sketch as written.

    The sketch's bytes are kept as they are (the published firmware's
    comments are GBK-encoded Chinese); ``#line`` makes the compiler's errors
    point into the sketch itself.
    """
    protos = b"".join(head + b";\n" for head in prototypes(data))
    return b"#include <Arduino.h>\n" + protos + b"#line 1 " + c_string(name) + b"\n" + data


def c_string(text: str) -> bytes:
    """``text`` as a C string literal, quotes included: what is not a plain printable ASCII character is an
    octal escape, so a file name holding a quote, a backslash or a newline stays one string, never code."""
    plain = set(b"abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 _-.,+=()[]{}@#%&!~^:;/")
    raw = os.fsencode(text)
    return b'"' + b"".join(bytes((b,)) if b in plain else b"\\%03o" % b for b in raw) + b'"'


def prototypes(data: bytes) -> list[bytes]:
    """The head of every function the sketch defines at file scope, in order.

    As the Arduino IDE did before ctags: with comments, strings and
    preprocessor lines blanked, each ``{`` at brace depth 0 whose preceding
    text (since the last ``;``, ``{`` or ``}``) reads ``type name(params)``
    opens a function definition.
    """
    text = _DIRECTIVE.sub(lambda m: b" " * len(m[0]), _COMMENT_OR_STRING.sub(_blank, data))
    heads: list[bytes] = []
    depth, start = 0, 0
    for i, byte in enumerate(text):
        if byte == ord("{"):
            if depth == 0:
                head = b" ".join(text[start:i].split())
                match = _HEAD.match(head)
                if match and match[1] not in _NOT_FUNCTIONS:
                    heads.append(head)
            depth += 1
        elif byte == ord("}"):
            depth = max(0, depth - 1)
            start = i + 1
        elif byte == ord(";") and depth == 0:
            start = i + 1
    return heads


def _blank(match: re.Match[bytes]) -> bytes:
    """A comment or literal as spaces (newlines kept), so positions and line numbers stay."""
    return bytes(b if b == ord("\n") else ord(" ") for b in match[0])

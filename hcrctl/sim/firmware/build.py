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
compiler's first error and the path of the full log. Standard library only.
"""

from __future__ import annotations

import re
import subprocess
from collections.abc import Callable
from pathlib import Path

from ...errors import HcrError
from . import toolchain

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
    if suffix == ".elf":
        return path.resolve()
    if suffix == ".hex":
        key = toolchain.digest("hex", data)
        return toolchain.cached("firmware", key, "firmware.bin", lambda d: _hex_to_bin(path, data, d))
    toolchain.require(toolchain.BUILD_NEEDS)
    key = toolchain.digest(RECIPE, data, path.name, mcu, str(clock), _compiler_version())

    def build(out: Path) -> None:
        say(f"building {path.name} for {mcu} at {clock} Hz (cached for the next start)")
        _build(path, data, mcu, clock, out)

    return toolchain.cached("firmware", key, "firmware.elf", build)


def read_firmware(path: Path) -> bytes:
    """The file's bytes, or the one line saying why it cannot be read."""
    try:
        return path.read_bytes()
    except OSError as exc:
        raise HcrError(f"cannot read the firmware {path}: {exc.strerror or exc}") from None


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
    with log.open("wb") as sink:
        steps = [
            ["avr-gcc", "-c", *flags, *_C, *map(str, sorted(core.glob("*.c")))],
            ["avr-g++", "-c", *flags, *_CXX, *map(str, sorted(core.glob("*.cpp"))), str(sketch)],
            ["avr-gcc", "-c", *flags, "-x", "assembler-with-cpp", *map(str, sorted(core.glob("*.S")))],
        ]
        procs = [subprocess.Popen(cmd, cwd=out, stdout=sink, stderr=sink) for cmd in steps]
        if any(proc.wait() != 0 for proc in procs):
            raise _failed(path, log)
        objects = sorted(str(p) for p in out.glob("*.o"))
        link = ["avr-g++", f"-mmcu={mcu}", "-Os", "-Wl,--gc-sections", *objects, "-o", "firmware.elf", "-lm"]
        if subprocess.run(link, cwd=out, stdout=sink, stderr=sink, check=False).returncode != 0:
            raise _failed(path, log)
    for obj in objects:
        Path(obj).unlink()


def _failed(path: Path, log: Path) -> HcrError:
    """The compiler's first error as one line, and where the whole log is."""
    text = log.read_text(errors="replace")
    first = next((line for line in text.splitlines() if "error" in line.lower()), "the build failed")
    return HcrError(f"cannot build {path.name}: {first.strip()}", hint=f"the full log is {log}")


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
    return b"#include <Arduino.h>\n" + protos + f'#line 1 "{name}"\n'.encode() + data


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


def _hex_to_bin(path: Path, data: bytes, out: Path) -> None:
    """An Intel HEX file as the flash image it describes (gaps filled with 0xFF, as erased flash)."""
    image = bytearray()
    base = 0
    for number, line in enumerate(data.decode("ascii", "replace").splitlines(), 1):
        line = line.strip()
        if not line:
            continue
        try:
            record = bytes.fromhex(line[1:]) if line[0] == ":" else b""
        except ValueError:
            record = b""
        if len(record) < 5 or len(record) != record[0] + 5 or sum(record) & 0xFF:
            raise HcrError(f"{path.name} line {number} is not an Intel HEX record")
        count, address, kind, payload = record[0], int.from_bytes(record[1:3], "big"), record[3], record[4:-1]
        if kind == 0:
            at = base + address
            image.extend(b"\xff" * max(0, at + count - len(image)))
            image[at : at + count] = payload
        elif kind == 2:
            base = int.from_bytes(payload, "big") << 4
        elif kind == 4:
            base = int.from_bytes(payload, "big") << 16
        elif kind == 1:
            break
    (out / "firmware.bin").write_bytes(bytes(image))

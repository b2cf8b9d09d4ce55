"""``hcrctl sim --firmware``'s errors: one line each, exit 2 for usage, exit 1 for what cannot be done."""

from __future__ import annotations

import os
import re
import signal
import struct
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from helpers import TIMEOUT, hcrctl_exe

from hcrctl.sim.firmware.build import prototypes, sketch_source
from hcrctl.sim.firmware.pins import DEFAULTS, PinMap, PinMapError
from hcrctl.sim.firmware.toolchain import INSTALL, missing_reason


def sim(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [hcrctl_exe(), "sim", *args],
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        stdin=subprocess.DEVNULL,
        env=env,
    )


def one_line(result: subprocess.CompletedProcess[str], code: int) -> str:
    assert result.returncode == code, (result.returncode, result.stderr)
    assert result.stdout == "" and len(result.stderr.splitlines()) == 1, result.stderr
    return result.stderr


@pytest.mark.parametrize(
    ("pins", "named"),
    [
        ("motor1=4", "motor1 must be a PWM pin (3, 5, 6, 9, 10, 11); got '4'"),
        ("bump_left=1", "bump_left must be a digital pin 2..13 (0 and 1 are the UART)"),
        ("ir3=A9", "ir3 must be an analog input A0..A7"),
        ("wheel=3", "expected name=pin with a name of motor1, motor2, light"),
        ("light=12", "pin 12 is given to both light and bump_right"),
        ("light=3,light=4", "light is given twice"),
    ],
)
def test_a_bad_pin_map_is_a_usage_error_naming_what_is_allowed(tmp_path: Path, pins: str, named: str) -> None:
    sketch = tmp_path / "x.ino"
    sketch.write_text("void setup() {}\nvoid loop() {}\n")
    err = one_line(sim("--firmware", str(sketch), "--pins", pins), 2)
    assert "'--pins'" in err and named in err, err


def test_a_pin_map_keeps_the_published_wiring_for_roles_it_does_not_name() -> None:
    pins = PinMap.parse("motor1=9, motor2=10, bump_left=4, ir1=a7")
    assert (pins["motor1"], pins["motor2"], pins["bump_left"], pins["ir1"]) == (9, 10, 4, 7)
    assert all(
        pins[role] == pin
        for role, pin in DEFAULTS.items()
        if role not in ("motor1", "motor2", "bump_left", "ir1")
    )
    with pytest.raises(PinMapError):
        PinMap.parse("ir1=A6")  # A6 is ir7's


@pytest.mark.parametrize(
    "extra",
    [["--tcp", "0"], ["--protocol", "v0.11"], ["--wander"], ["--options", "drop=0.1"], ["--baud", "9600"]],
)
def test_the_models_options_do_not_go_with_a_firmware(tmp_path: Path, extra: list[str]) -> None:
    err = one_line(sim("--firmware", str(tmp_path / "x.ino"), *extra), 2)
    assert "cannot go with --firmware" in err and extra[0] in err, err


def test_chip_options_need_a_firmware() -> None:
    err = one_line(sim("--pty", "--mcu", "atmega168"), 2)
    assert "--mcu goes with --firmware" in err, err


def test_a_file_that_is_no_firmware_is_a_usage_error(tmp_path: Path) -> None:
    err = one_line(sim("--firmware", str(tmp_path / "notes.txt")), 2)
    assert "'--firmware'" in err and ".pde, .ino, .elf, .hex" in err, err


def test_a_missing_package_is_one_line_with_the_install_command(tmp_path: Path) -> None:
    sketch = tmp_path / "x.ino"
    sketch.write_text("void setup() {}\nvoid loop() {}\n")
    env = {**os.environ, "PATH": str(Path(sys.executable).parent), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    err = one_line(sim("--firmware", str(sketch), env=env), 1)  # neither avr-g++ nor cc on this PATH
    assert "needs the Debian packages" in err and "gcc-avr" in err and INSTALL in err, err


@pytest.mark.skipif(missing_reason() is not None, reason=missing_reason() or "")
def test_a_sketch_that_does_not_compile_is_its_first_error_and_the_log(tmp_path: Path) -> None:
    sketch = tmp_path / "broken.ino"
    sketch.write_text("void setup() {\n  undeclared_thing(1);\n}\nvoid loop() {}\n")
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")}
    result = sim("--firmware", str(sketch), env=env)
    assert result.returncode == 1 and result.stdout == "", result.stderr
    building, err = result.stderr.splitlines()  # what it is doing, then the one error line
    assert (
        building
        == "hcrctl: sim: building broken.ino for atmega328p at 16000000 Hz (cached for the next start)"
    )
    assert "cannot build broken.ino: broken.ino:2" in err and "undeclared_thing" in err, err
    log = Path(err.rsplit("the full log is ", 1)[1].rstrip(")\n"))
    assert "undeclared_thing" in log.read_text()


def test_a_firmware_file_that_is_not_there_is_one_line(tmp_path: Path) -> None:
    err = one_line(sim("--firmware", str(tmp_path / "gone.elf")), 1)
    assert "cannot read the firmware" in err and "gone.elf" in err, err


def test_a_sketch_gets_a_prototype_for_each_function_it_defines() -> None:
    sketch = b"""#define N 3 // a comment with f(int x) {
byte header[2]={0x55,0xaa};
const char *s = "void g() {";
void setup()
{
  Serial.begin(9600);
}
/* int hidden(int) { */
boolean Check(byte cmd[],int length)
{
  if (length) { return true; }
  return false;
}
unsigned int *where(int pin, float k) { return 0; }
struct Pose { int x; };
void loop() { Check(header, 2); }
"""
    assert prototypes(sketch) == [
        b"void setup()",
        b"boolean Check(byte cmd[],int length)",
        b"unsigned int *where(int pin, float k)",
        b"void loop()",
    ]
    source = sketch_source(sketch, "x.ino")
    assert source.startswith(b"#include <Arduino.h>\nvoid setup();\n") and source.endswith(sketch)
    assert b'#line 1 "x.ino"\n' + sketch in source


#: Another robot's sketch: motors on timer 1 (pins 9, 10), its front bumper on pin 4 lights pin 13.
OTHER_WIRING = """
void setup() {
  Serial.begin(9600);
  pinMode(4, INPUT);
  pinMode(13, OUTPUT);
  digitalWrite(13, HIGH);
  forward(250);
}
void loop() {
  digitalWrite(13, digitalRead(4));  // a pressed bumper reads low: the light (active low) comes on
}
void forward(int pwm) {  // defined after its first use: the build adds the prototype
  analogWrite(9, pwm);
  analogWrite(10, pwm);
}
"""


#: Pin 10 is the published firmware's left bumper: that one moves too, or the map is refused.
PINS = "motor1=9,motor2=10,bump_left=7,bump_centre=4,light=13"


@pytest.mark.skipif(missing_reason() is not None, reason=missing_reason() or "")
def test_pins_wire_another_sketch_into_the_world(tmp_path: Path) -> None:
    sketch = tmp_path / "other.ino"
    sketch.write_text(OTHER_WIRING)
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")}
    proc = subprocess.Popen(
        [
            hcrctl_exe(),
            "sim",
            "--firmware",
            str(sketch),
            "--pins",
            PINS,
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
    )
    assert proc.stderr is not None
    said: list[str] = []
    try:
        for line in proc.stderr:  # the robot drives east into the wall, and its bumper lights the light
            said.append(line.strip())
            if "light on (pin 13 low)" in line:
                break
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=TIMEOUT)
    assert any(re.search(r"motors: PWM 9=250 10=250 at x 60 cm", s) for s in said), said
    assert any("bumpers: centre pressed at x 285 cm" in s for s in said), said
    assert said[-1].endswith("light on (pin 13 low)"), said


# -- hostile firmware files: one line each, before anything is allocated for them ------------------


def hex_record(kind: int, address: int, payload: bytes) -> str:
    body = bytes([len(payload)]) + address.to_bytes(2, "big") + bytes([kind]) + payload
    return ":" + (body + bytes([-sum(body) & 0xFF])).hex().upper() + "\n"


END = hex_record(1, 0, b"")


@pytest.mark.parametrize(
    ("records", "said"),
    [
        # a segment address of 200 bytes: int.from_bytes(...) << 4 overflowed the image's size
        (hex_record(2, 0, bytes(200)) + END, "line 1: a type 02 record holds 2 bytes, not 200"),
        # 4 GB up: the image was grown to 4 GB for one byte
        (
            hex_record(4, 0, b"\xff\xff") + hex_record(0, 0, b"\x00") + END,
            "line 2 puts 1 byte at 0xFFFF0000, outside the 32 KiB flash of atmega328p",
        ),
        (
            hex_record(0, 0x7FFF, b"\x00\x00") + END,
            "line 1 puts 2 bytes at 0x7FFF, outside the 32 KiB flash of atmega328p",
        ),
        (hex_record(9, 0, b"") + END, "line 1 is a record of type 09; Intel HEX has 00-05"),
        (":" + "00" * 600 + "\n", "line 1 is not an Intel HEX record"),
    ],
)
def test_a_hostile_hex_file_is_one_line(tmp_path: Path, records: str, said: str) -> None:
    path = tmp_path / "hostile.hex"
    path.write_text(records)
    err = one_line(sim("--firmware", str(path), env={**os.environ, "XDG_CACHE_HOME": str(tmp_path)}), 1)
    assert err == f"hcrctl: error: hostile.hex is not a firmware the emulated chip can run: {said}\n", err


def test_a_hex_file_fits_the_chip_it_is_run_on(tmp_path: Path) -> None:
    """The same 24 KiB image is within the ATmega328P's 32 KiB, and refused for the ATmega168's 16 KiB."""
    from hcrctl.sim.firmware.image import hex_image

    data = "".join(hex_record(0, at, bytes(16)) for at in range(0x5FF0, 0x6000, 16)) + END
    assert len(hex_image("x.hex", data.encode(), "atmega328p")) == 0x6000
    path = tmp_path / "big.hex"
    path.write_text(data)
    result = sim(
        "--firmware", str(path), "--mcu", "atmega168", env={**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    )
    assert "outside the 16 KiB flash of atmega168" in one_line(result, 1)


def elf32(sections: list[tuple[str, int, bytes, int, int]], machine: int = 83, shentsize: int = 40) -> bytes:
    """A little ELF32 executable: (name, type, bytes, link, entsize) per section after the null one."""
    names = b"\0" + b"".join(name.encode() + b"\0" for name, *_ in sections) + b".shstrtab\0"
    body, headers, at = b"", [bytes(40)], 52
    offsets = []
    for name, kind, data, link, entsize in sections:
        offsets.append(names.index(name.encode() + b"\0"))
        headers.append(
            struct.pack(
                "<IIIIIIIIII", offsets[-1], kind, 0, 0, at + len(body), len(data), link, 0, 1, entsize
            )
        )
        body += data
    headers.append(
        struct.pack("<IIIIIIIIII", names.index(b".shstrtab"), 3, 0, 0, at + len(body), len(names), 0, 0, 1, 0)
    )
    body += names
    shoff = at + len(body)
    head = b"\x7fELF\x01\x01\x01" + bytes(9)
    head += struct.pack(
        "<HHIIIIIHHHHHH", 2, machine, 1, 0, 0, shoff, 0, 52, 32, 0, shentsize, len(headers), len(headers) - 1
    )
    return head + body + b"".join(headers)


PROGBITS, SYMTAB, STRTAB = 1, 2, 3
CODE = (".text", PROGBITS, b"\x0c\x94\x00\x00" * 4, 0, 0)


@pytest.mark.parametrize(
    ("make", "said"),
    [
        (lambda: Path("/bin/true").read_bytes(), "it is built for x86-64, not AVR"),
        (lambda: elf32([CODE], machine=40), "it is built for ARM, not AVR"),
        (lambda: elf32([CODE], shentsize=64), "its section table is damaged or outside the file"),
        (lambda: elf32([CODE])[:-20], "its section table is damaged or outside the file"),
        (
            lambda: elf32([(".text", PROGBITS, bytes(40 << 10), 0, 0)]),
            "do not fit the 32 KiB flash of atmega328p",
        ),
        (lambda: elf32([(".text", 8, b"", 0, 0)]), "its .text section holds no bytes of the file"),
        (lambda: elf32([(".data", PROGBITS, b"\0", 0, 0)]), "it has no .text section (no code)"),
        # entries of size 0: simavr divided the table's size by it
        (
            lambda: elf32([CODE, (".symtab", SYMTAB, bytes(16), 3, 0), (".strtab", STRTAB, b"\0", 0, 0)]),
            "its symbol table is damaged",
        ),
        # a symbol named past the end of its string table: simavr's strcpy read a null pointer
        (
            lambda: elf32(
                [
                    CODE,
                    (".symtab", SYMTAB, struct.pack("<IIIBBH", 999, 0, 0, 0x12, 0, 1), 3, 16),
                    (".strtab", STRTAB, b"\0", 0, 0),
                ]
            ),
            "a symbol name lies outside its string table",
        ),
        # simavr writes a VCD trace file the firmware names, on the host
        (
            lambda: elf32([CODE, (".mmcu", PROGBITS, bytes([12, 8]) + b"/tmp/x\0\0", 0, 0)]),
            "its .mmcu section asks the emulator for more than the chip (tag 12)",
        ),
        # a chip name with no end: simavr's strcpy into 64 bytes ran on
        (
            lambda: elf32([CODE, (".mmcu", PROGBITS, bytes([1, 100]) + b"A" * 100, 0, 0)]),
            "its .mmcu chip name is longer than 63 bytes",
        ),
        (lambda: elf32([CODE, (".lock", PROGBITS, b"\xff", 0, 0)]), "a .lock section without .fuse"),
    ],
)
def test_a_hostile_elf_is_one_line_and_never_reaches_the_harness(
    tmp_path: Path, make: Callable[[], bytes], said: str
) -> None:
    path = tmp_path / "hostile.elf"
    path.write_bytes(make())
    err = one_line(sim("--firmware", str(path), env={**os.environ, "XDG_CACHE_HOME": str(tmp_path)}), 1)
    assert err.startswith("hcrctl: error: hostile.elf is not a firmware the emulated chip can run: "), err
    assert said in err, err


def test_a_firmware_file_larger_than_any_firmware_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / "huge.hex"
    with path.open("wb") as handle:
        handle.truncate(9 << 20)  # sparse: nothing is written, and nothing past 8 MiB is read
    err = one_line(sim("--firmware", str(path), env={**os.environ, "XDG_CACHE_HOME": str(tmp_path)}), 1)
    assert "huge.hex is not a firmware the emulated chip can run: it is larger than 8 MiB" in err, err


def test_a_pin_number_of_ten_thousand_digits_is_a_usage_error_cut_short(tmp_path: Path) -> None:
    sketch = tmp_path / "x.ino"
    sketch.write_text("void setup() {}\nvoid loop() {}\n")
    err = one_line(sim("--firmware", str(sketch), "--pins", "motor1=" + "9" * 10_000), 2)
    assert "'--pins'" in err and "motor1 must be a PWM pin (3, 5, 6, 9, 10, 11)" in err, err
    assert len(err) < 400 and "Traceback" not in err, err


@pytest.mark.parametrize("digits", ["٥", "00005", "+5", "5.0"])
def test_a_pin_is_plain_ascii_digits(digits: str) -> None:
    with pytest.raises(PinMapError, match="motor1 must be a PWM pin"):
        PinMap.parse(f"motor1={digits}")


HOSTILE_NAME = 'x"\n#error injected by the file name\n\\.ino'


def test_a_sketch_file_name_is_a_c_string_in_the_source_never_code() -> None:
    source = sketch_source(b"void setup() {}\n", HOSTILE_NAME)
    assert b'#line 1 "x\\042\\012#error injected by the file name\\012\\134.ino"\n' in source
    assert b"\n#error" not in source
    assert sketch_source(b"", "caf\u00e9 1.ino").count(b'"caf\\303\\251 1.ino"') == 1  # UTF-8, escaped


@pytest.mark.skipif(missing_reason() is not None, reason=missing_reason() or "")
def test_a_sketch_whose_name_holds_a_directive_builds_as_any_sketch(tmp_path: Path) -> None:
    """The name's ``#error`` line failed the build when the name was pasted into ``#line`` unquoted."""
    sketch = tmp_path / HOSTILE_NAME
    sketch.write_text("void setup() {}\nvoid loop() {}\n")
    proc = subprocess.Popen(
        [hcrctl_exe(), "sim", "--firmware", str(sketch)],
        env={**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
    )
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()  # the pty's path once the chip runs; nothing if the build failed
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=TIMEOUT)
    assert first.startswith("/dev/"), err
    assert "injected" not in err.replace("#error injected by the file name", ""), err


@pytest.mark.skipif(missing_reason() is not None, reason=missing_reason() or "")
def test_a_sketch_that_includes_dev_zero_meets_the_builds_memory_bound(tmp_path: Path) -> None:
    sketch = tmp_path / "zero.ino"
    sketch.write_text('#include "/dev/zero"\nvoid setup() {}\nvoid loop() {}\n')
    result = sim("--firmware", str(sketch), env={**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")})
    assert result.returncode == 1 and result.stdout == "", result.stderr
    building, err = result.stderr.splitlines()
    assert building.startswith("hcrctl: sim: building zero.ino"), building
    assert err.startswith("hcrctl: error: cannot build zero.ino: ") and "out of memory" in err, err
    assert "a build is bounded to 1 GiB of memory" in err, err


@pytest.mark.skipif(missing_reason() is not None, reason=missing_reason() or "")
def test_a_built_elf_passes_the_check_and_runs(tmp_path: Path) -> None:
    """What avr-gcc links is accepted as it is: the checks refuse only what no build makes."""
    cache = tmp_path / "cache"
    sketch = tmp_path / "blink.ino"
    sketch.write_text("void setup() { pinMode(13, OUTPUT); }\nvoid loop() { digitalWrite(13, HIGH); }\n")
    env = {**os.environ, "XDG_CACHE_HOME": str(cache)}
    for firmware in (sketch, None):
        if firmware is None:  # then the ELF that build made, copied out as a user's .elf
            firmware = tmp_path / "blink.elf"
            firmware.write_bytes(next(cache.glob("hcrctl/firmware/*/firmware.elf")).read_bytes())
        proc = subprocess.Popen(
            [hcrctl_exe(), "sim", "--firmware", str(firmware)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
        )
        try:
            assert proc.stdout is not None
            first = proc.stdout.readline()
        finally:
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=TIMEOUT)
        assert first.startswith("/dev/"), err

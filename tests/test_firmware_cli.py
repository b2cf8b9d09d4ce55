"""``hcrctl sim --firmware``'s errors: one line each, exit 2 for usage, exit 1 for what cannot be done."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
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

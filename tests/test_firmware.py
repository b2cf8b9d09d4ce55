"""The published firmware in the loop: ``hcrctl sim --firmware HCR_romeo.pde`` against the installed hcrctl.

The real v0.33 firmware runs on an emulated ATmega328P (simavr) in the
simulator's world, so these tests check hcrctl's reading of v0.11 against the
firmware itself, not against hcrctl's own model of it. The sim's stderr says
what the chip's pins do (motor PWM, the light, the bumpers) and where the robot
is; the tests read it and the wire, and wait for conditions, never for fixed
times.

They skip, with one line saying why, when a Debian package is missing (the
line ``hcrctl sim --firmware`` itself prints) or when the firmware is not
found: ``$HCRCTL_FIRMWARE``, else ``tests/data/firmware/HCR_romeo.pde`` (test
data kept in the repository, not part of the package; see its README).
"""

from __future__ import annotations

import json
import os
import re
import select
import signal
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from helpers import TIMEOUT, hcrctl_exe, wait_until

from hcrctl.sim.behaviours import ir_angles
from hcrctl.sim.body import Body
from hcrctl.sim.firmware.toolchain import missing_reason

ROOT = Path(__file__).resolve().parent.parent
FIRMWARE = Path(os.environ.get("HCRCTL_FIRMWARE") or ROOT / "tests" / "data" / "firmware" / "HCR_romeo.pde")
V011 = ["--protocol", "v0.11"]
BANNER = b"HCR Start\r\n"


def _skip_reason() -> str | None:
    if not FIRMWARE.is_file():
        return f"the published firmware is not at {FIRMWARE} (set HCRCTL_FIRMWARE to HCR_romeo.pde)"
    return missing_reason()


pytestmark = pytest.mark.skipif(_skip_reason() is not None, reason=_skip_reason() or "")

#: A motor line of the sim's stderr: "motors: PWM 5=192 6=192 at x 60 cm, y 100 cm, heading 90°".
MOTORS = re.compile(r"motors: PWM 5=(\w+) 6=(\w+) at x (-?\d+) cm, y (-?\d+) cm, heading (\d+)°")


class FirmwareSim:
    """``hcrctl sim --firmware``: its pty path, and its stderr lines as they come (read by a thread)."""

    def __init__(self, env: dict[str, str], *options: str, firmware: Path = FIRMWARE) -> None:
        self.proc = subprocess.Popen(
            [hcrctl_exe(), "sim", "--firmware", str(firmware), *options],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        assert self.proc.stdout is not None
        self.port = self.proc.stdout.readline().strip()
        assert self.port.startswith("/dev/"), (self.port, self.lines)

    def _read(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.lines.append(line.rstrip("\n"))

    def wait_for(self, pattern: str, after: int = 0) -> tuple[int, re.Match[str]]:
        """The first stderr line from index ``after`` on matching ``pattern``: (its index, the match)."""

        def found() -> tuple[int, re.Match[str]] | None:
            for i, line in enumerate(self.lines[after:], after):
                match = re.search(pattern, line)
                if match:
                    return i, match
            return None

        result: tuple[int, re.Match[str]] = wait_until(found, what=f"{pattern!r} from the sim: {self.lines}")
        return result

    def motors(self, pwm: tuple[int, int], after: int = 0) -> tuple[int, re.Match[str]]:
        """The first motor line from ``after`` on with this PWM on pins 5 and 6."""
        return self.wait_for(rf"motors: PWM 5={pwm[0]} 6={pwm[1]} at", after)

    def close(self) -> str:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(timeout=TIMEOUT)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait()
        self._reader.join(TIMEOUT)
        return "\n".join(self.lines)


@pytest.fixture(scope="session")
def firmware_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """An environment whose build cache is shared by the session: the firmware is built once, here."""
    base = tmp_path_factory.getbasetemp()
    cache = (base.parent if base.name.startswith("popen-gw") else base) / "firmware-cache"
    env = {k: v for k, v in os.environ.items() if not k.startswith("HCRCTL_")}
    env.update(XDG_CACHE_HOME=str(cache), XDG_CONFIG_HOME=str(base / "config"), COLUMNS="100")
    warm = FirmwareSim(env)  # builds the sketch and the harness into the cache, or finds them there
    warm.close()
    return env


@pytest.fixture
def sim(firmware_env: dict[str, str]) -> Iterator[FirmwareSim]:
    chip = FirmwareSim(firmware_env)
    try:
        yield chip
    finally:
        chip.close()


def hcrctl(sim: FirmwareSim, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [hcrctl_exe(), "--port", sim.port, *args],
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        stdin=subprocess.DEVNULL,
        env={k: v for k, v in os.environ.items() if not k.startswith("HCRCTL_")},
    )


def held_drive(sim: FirmwareSim, left: int, right: int) -> subprocess.Popen[str]:
    """``drive power L R`` held until SIGINT (it then sends stop, and exits 130 as Ctrl-C does)."""
    return subprocess.Popen(
        [hcrctl_exe(), *V011, "--port", sim.port, "drive", "power", str(left), str(right)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def end_drive(drive: subprocess.Popen[str]) -> str:
    drive.send_signal(signal.SIGINT)
    _, err = drive.communicate(timeout=TIMEOUT)
    assert drive.returncode == 130, err
    return err


def test_the_firmware_boots_with_its_banner(sim: FirmwareSim) -> None:
    """The chip boots as the sim starts; its first bytes wait in the pty for the first reader.

    Read from the wire itself: hcrctl's opening of a port flushes what waited
    there (pyserial's reset of the input buffer), as a real board's banner is
    gone by the time a program opens its port unless the opening resets it.
    """
    fd = os.open(sim.port, os.O_RDWR | os.O_NOCTTY)
    try:
        heard = b""

        def banner() -> bool:
            nonlocal heard
            ready, _, _ = select.select([fd], [], [], 0.1)
            heard += os.read(fd, 4096) if ready else b""
            return len(heard) >= len(BANNER)

        wait_until(banner, what="the firmware's first bytes")
    finally:
        os.close(fd)
    assert heard.startswith(BANNER), heard[:40]


def test_read_bump_ir_and_everything(sim: FirmwareSim) -> None:
    bump = hcrctl(sim, *V011, "--json", "read", "bump")
    assert bump.returncode == 0, bump.stderr
    assert json.loads(bump.stdout) == {
        "bump": [False, False, False]
    }  # nothing touches the robot at its start

    # The IR readings come from the world through the ADC and the firmware's own GP2D12 formula; its
    # smoothing climbs from 0 and settles, the sensor nearest an obstacle lowest.
    world = [Body().range_at(a) for a in ir_angles(7)]
    nearest = world.index(min(world))

    def settled() -> list[int] | None:
        result = hcrctl(sim, *V011, "--json", "read", "ir")
        assert result.returncode == 0, result.stderr
        ir: list[int] = json.loads(result.stdout)["ir"]
        others = [v for i, v in enumerate(ir) if i != nearest]
        return ir if ir[nearest] < min(others) else None

    ir = wait_until(settled, what="the IR nearest the bin to read lowest")
    assert len(ir) == 7 and all(0 <= v <= 80 for v in ir), ir

    everything = hcrctl(sim, *V011, "--json", "read")
    assert everything.returncode == 0, everything.stderr
    assert set(json.loads(everything.stdout)) == {"bump", "ir"}


def test_drive_power_sets_the_pwm_pins_and_the_stop_after_it_resets_them(sim: FirmwareSim) -> None:
    result = hcrctl(sim, *V011, "drive", "power", "50", "50", "--for", "1")
    assert result.returncode == 0, result.stderr
    moving, _ = sim.motors((192, 192))  # +50 % is 0xC0: the firmware writes it to timer 0 as is
    stopped, _ = sim.motors((127, 127), after=moving)  # the host's stop 0x80 is the firmware's 127
    where = MOTORS.search(sim.lines[stopped])
    # The robot drove east from x 60 cm: how far depends on how much of the second the emulated board was
    # given (a loaded machine slows the emulation), so east is what is checked, not a distance.
    assert where is not None and int(where[3]) > 60, sim.lines


def test_stop_sets_both_motors_to_the_firmwares_stop(sim: FirmwareSim) -> None:
    stop = hcrctl(sim, *V011, "stop")
    assert stop.returncode == 0, stop.stderr
    sim.motors((127, 127))  # from pins the firmware had not driven yet: the host's 0x80 is its 127


def test_monitor_shows_both_firmware_checksum_quirks(sim: FirmwareSim) -> None:
    result = hcrctl(sim, *V011, "--json", "monitor", "--duration", "1.5")
    assert result.returncode == 0, result.stderr
    rows = [json.loads(line) for line in result.stdout.splitlines()]
    rules = {row["name"]: row["matched"] for row in rows if row.get("checksum_ok")}
    # bump: address + length + command (its payload left out); IR: the last IR byte
    assert rules == {"bump": "address+length+command", "ir": "last IR byte"}, rows[:6]


def test_watch_sees_the_firmwares_stream(sim: FirmwareSim) -> None:
    result = hcrctl(sim, *V011, "--json", "watch", "--duration", "2")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["sweeps"] > 0 and summary["timeouts"] == 0, summary
    assert summary["latest"]["bump"] == {"bump": [False, False, False]}
    assert len(summary["latest"]["ir"]["ir"]) == 7


def test_driving_into_a_wall_presses_a_bumper_and_the_firmware_turns_the_robot_away(sim: FirmwareSim) -> None:
    drive = held_drive(sim, 100, 100)  # east, from x 60 cm towards the wall at 300 cm
    try:
        pressed, hit = sim.wait_for(r"bumpers: centre pressed at x (\d+) cm, y \d+ cm, heading (\d+)°")
        # The firmware's own bumper handler (BumperValue 0x05): stop, 0xB0 on both, then spin 0x40/0xB0
        spin, _ = sim.motors((64, 176), after=pressed)
        sim.wait_for("bumpers: none pressed", after=pressed)
        done, _ = sim.motors((127, 127), after=spin)
    finally:
        end_drive(drive)
    end = MOTORS.search(sim.lines[done])
    assert end is not None and int(hit[1]) > 250, sim.lines
    turned = abs((int(end[5]) - int(hit[2]) + 180) % 360 - 180)
    assert turned > 90, sim.lines  # it faces away from the wall now


def test_the_light_command_lights_the_pin(sim: FirmwareSim) -> None:
    result = hcrctl(sim, *V011, "hex", "send", "55 AA 01 01 14 FF")
    assert result.returncode == 0, result.stderr
    on, _ = sim.wait_for(r"light on \(pin 2 low\)")
    # the firmware's motion-sensor check turns it off again in its next loop (pin 3 reads low)
    sim.wait_for(r"light off \(pin 2 high\)", after=on)


def test_without_protocol_read_and_ping_name_v011_in_their_hint(sim: FirmwareSim) -> None:
    read = hcrctl(sim, "read", "bump")
    assert read.returncode == 1
    assert "try --protocol v0.11" in read.stderr and len(read.stderr.splitlines()) == 1, read.stderr
    ping = hcrctl(sim, "ping", "--count", "2")
    assert ping.returncode == 1
    assert "(try --protocol v0.11)" in ping.stdout, ping.stdout
    assert "hint: try --protocol v0.11" in ping.stderr, ping.stderr


def test_without_protocol_monitor_decodes_the_frames_it_hears(sim: FirmwareSim) -> None:
    result = hcrctl(sim, "--json", "monitor", "--duration", "2")
    assert result.returncode == 0, result.stderr
    rows = [json.loads(line) for line in result.stdout.splitlines()]
    frames = [row for row in rows if row.get("checksum_ok")]
    assert {row["name"] for row in frames} == {"bump", "ir"}, rows[:6]
    assert sum(row.get("problem") == "malformed" for row in rows) <= 1, rows
    assert "decoding them as v0.11" in result.stderr, result.stderr


def test_a_built_hex_runs_as_the_sketch_does(firmware_env: dict[str, str], tmp_path: Path) -> None:
    """The .hex an Arduino IDE exports (here made from the cached build) runs without building anything."""
    elf = next(Path(firmware_env["XDG_CACHE_HOME"], "hcrctl", "firmware").glob("*/firmware.elf"))
    hex_file = tmp_path / "HCR_romeo.hex"
    subprocess.run(["avr-objcopy", "-O", "ihex", "-R", ".eeprom", str(elf), str(hex_file)], check=True)
    chip = FirmwareSim(firmware_env, "--mcu", "atmega328p", "--clock", "16000000", firmware=hex_file)
    try:
        bump = hcrctl(chip, *V011, "--json", "read", "bump")
        assert bump.returncode == 0, bump.stderr
        assert json.loads(bump.stdout) == {"bump": [False, False, False]}
    finally:
        chip.close()

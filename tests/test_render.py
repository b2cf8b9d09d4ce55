"""The pure renderers: readings as a table, as plain lines and as JSON; ports as a table."""

from __future__ import annotations

import io

import pytest
from rich.console import Console

from hcrctl.link.ports import PortInfo
from hcrctl.protocol import commands as C
from hcrctl.render import readings as render
from hcrctl.render.ports import ports_table

READINGS = {
    "bump": C.Bumpers((False, True, True)),
    "ir": C.Infrared((12, 40, 33, 8, 0)),
    "sonar": C.Ultrasonic((120, 80, 200)),
    "compass": C.Compass(123.4),
    "wheels": C.WheelSpeed((20, 21)),
    "env": C.Environment(86, -3),
}


def draw(renderable, width: int = 60) -> str:
    console = Console(width=width, record=True, color_system=None, file=io.StringIO())
    console.print(renderable)
    return console.export_text()


@pytest.mark.parametrize(
    ("heading", "name"),
    [(0, "N"), (11.0, "N"), (12.0, "NNE"), (90, "E"), (180, "S"), (270, "W"), (348.0, "NNW"), (359.9, "N")],
)
def test_cardinal_directions(heading, name):
    assert render.cardinal(heading) == name


def test_bumpers_by_name():
    assert render.bumper_text((False, True, True)) == "hit: front, right"
    assert render.bumper_text((True, False, False)) == "hit: left"
    assert render.bumper_text((False, False, False)) == "clear"


def test_table_has_every_reading_with_units():
    text = draw(render.readings_table(READINGS))
    for expected in ("hit: front, right", "12  40  33  8  0 (raw)", "120  80  200 cm", "123.4° ESE",
                     "left 20 cm/s  right 21 cm/s", "-3 °C", "86 %"):  # fmt: skip
        assert expected in text
    assert "╭" in text  # borders on a terminal


def test_plain_text_is_aligned_without_trailing_spaces():
    lines = render.readings_text(READINGS).splitlines()
    assert [line.split()[0] for line in lines] == [
        "bumpers", "infrared", "ultrasonic", "compass", "wheels", "temperature", "humidity"
    ]  # fmt: skip
    assert len({line.index(line.split()[1]) for line in lines}) == 1  # values in one column
    assert all(line == line.rstrip() for line in lines)


def test_json_keys_are_the_agreed_ones():
    doc = render.readings_json(READINGS)
    assert doc == {
        "bump": [False, True, True],
        "ir": [12, 40, 33, 8, 0],
        "sonar": [120, 80, 200],
        "heading": 123.4,
        "wheels": [20, 21],
        "humidity": 86,
        "temperature": -3,
    }


def test_ports_table_shows_the_by_id_link():
    ports = [
        PortInfo(
            "/dev/ttyUSB0", "FT232R USB UART", "USB VID:PID=0403:6001", "/dev/serial/by-id/usb-FTDI-if00"
        ),
        PortInfo("/dev/ttyS0", "n/a", "n/a", None),
    ]
    text = draw(ports_table(ports), width=120)
    assert "/dev/serial/by-id/usb-FTDI-if00" in text and "FT232R USB UART" in text
    row = next(line for line in text.splitlines() if "/dev/ttyS0" in line)
    assert " - " in row

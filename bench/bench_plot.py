"""What does a ``plot`` frame cost, at 10 Hz and at a 1 kHz poll, against a ``watch`` dashboard frame?

Run from the repository root: ``python bench/bench_plot.py``. It prints the figures, writes
``bench/results/plot.json`` and exits 1 if a target is missed. Every frame is drawn at 120x40 by
rich into memory, in one run, taking turns (``best_of_each``):

- watch: the full ``watch`` dashboard, every sensor, the baseline;
- plot_10hz: four series (two units) after 30 s of polling at 10 Hz;
- plot_1khz: the same four after 30 s at 1000 Hz (``--rate max`` on a fast link).

Target: a 1 kHz plot frame costs at most 5x a dashboard frame. The painter draws at most 20
frames a second, on its own thread; a dashboard frame is ~2 ms (4 % of a core at 20 fps), so
5x keeps the worst plot (sawtooth data, a full vertical stroke in every column) near a fifth of
a core. The history keeps each 1/600 of the window's lowest, highest and latest sample, so the
cost follows the chart's width, not the poll rate.
"""

from __future__ import annotations

import argparse
import io
import math
import sys

from _common import best_of_each, check, record
from rich.console import Console

from hcrctl.live.plot import plot_screen
from hcrctl.live.plotdata import PlotState
from hcrctl.live.screens import dashboard
from hcrctl.ops.livestate import LiveState
from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import encode
from hcrctl.protocol.series import find
from hcrctl.sim.options import SimOptions
from hcrctl.sim.simulator import Simulator

PATHS = ("compass.heading", "sonar.1", "wheels.left", "wheels.right")
WINDOW = 30.0


def fed(rate: float) -> PlotState:
    """A plot state after ``WINDOW`` seconds of replies at ``rate``."""
    clock = [0.0]
    state = PlotState(
        ["compass", "sonar", "wheels"],
        [find(p) for p in PATHS],
        WINDOW,
        target_rate=rate,
        clock=lambda: clock[0],
    )
    for k in range(int(WINDOW * rate)):
        clock[0] = k / rate
        state.record("compass", C.Compass(round(180 + 90 * math.sin(clock[0]), 1)), None)
        state.record("sonar", C.Ultrasonic((k % 200, 1, 2)), None)
        state.record("wheels", C.WheelSpeed((k % 50, k % 70)), None)
    return state


def simulated(cmd: C.Command) -> C.Reply:
    """The simulator's answer to a read of ``cmd``."""
    sim = Simulator(SimOptions(broadcast_hz=0, map_hz=0), clock=lambda: 0.0)
    (frame,) = decode_all(sim.feed(encode(0x01, cmd.code, b"")))
    assert cmd.reply is not None
    return cmd.reply.decode(frame.content)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20)
    args = parser.parse_args()
    console = Console(width=120, height=40, file=io.StringIO(), color_system="truecolor")
    watch = LiveState(C.SENSORS, target_rate=10)
    for name in C.SENSORS:
        watch.record(name, simulated(C.BY_NAME[name]), 0.001)
    slow, fast = fed(10.0), fed(1000.0)

    def frame(state: PlotState) -> None:
        console.print(plot_screen(state.view(), state.traces(), WINDOW, WINDOW))

    best = best_of_each(
        {
            "watch": lambda: console.print(dashboard(watch.view(), 1.0)),
            "plot_10hz": lambda: frame(slow),
            "plot_1khz": lambda: frame(fast),
        },
        args.repeat,
    )
    ms = {name: round(1000 * seconds, 2) for name, seconds in best.items()}
    ratio = best["plot_1khz"] / best["watch"]
    record("plot", {**{f"{k}_ms": v for k, v in ms.items()}, "plot_1khz_over_watch": round(ratio, 2)})
    return (
        0 if check("5 watch frames / one 1 kHz plot frame", 5 * best["watch"] / best["plot_1khz"], 1.0) else 1
    )


if __name__ == "__main__":
    sys.exit(main())

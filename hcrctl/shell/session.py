"""One shell session: the settings, the link, the broadcast counts, the current mode.

Shared by the interactive prompt and script mode, so both run lines the same
way. Nothing here imports prompt-toolkit: the prompt is one front end, a
script file is another.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

import click

from ..errors import HcrError
from ..errors.terminal import printable
from ..protocol.frames import Frame, TextLine
from .broadcasts import Broadcasts, news_line
from .link import SessionLink

if TYPE_CHECKING:
    from ..cli.embed import Settings
    from ..link.client import Robot
    from ..link.traffic import Traffic

Printer = Callable[[str], object]  # what it returns (a write's count) is ignored
#: Seconds the news of stations first heard is gathered before it is printed, as one line.
NEWS_WINDOW = 1.0


class Session:
    """What every line of one session shares."""

    def __init__(self, settings: Settings, *, interactive: bool) -> None:
        self.settings = settings
        self.interactive = interactive
        self.broadcasts = Broadcasts()
        self.link = SessionLink(settings, on_frame=self._unsolicited, on_event=self.say)
        #: What unsolicited frames print (see broadcasts.MODES); scripts stay quiet unless asked.
        self.monitor = "changes" if interactive else "off"
        self.hex_mode = False
        self.done = False
        self.stop_note: str | None = None  # the toolbar's "stop sent" notice
        #: Where asynchronous lines go; None while a command owns the terminal.
        self.printer: Printer | None = None
        #: ``moves.hcr:3`` while a script line runs: errors start with it.
        self.where: str | None = None
        self._held: list[str] = []  # notices that came while a command owned the terminal
        #: Stations (or kinds) first heard and not printed yet: no prompt could, or within NEWS_WINDOW.
        self._news: list[Frame] = []
        self._news_due: threading.Timer | None = None
        self._say_lock = threading.Lock()
        self._last_text: str | None = None  # the firmware's last printed line
        settings.robot_hooks.append(self._hear_text)

    # -- the prompt --------------------------------------------------------

    @property
    def prompt_text(self) -> str:
        """``hcr sim:// ok> `` normally, ``hex> `` in raw hex mode, ``hcr> `` in scripts."""
        if self.hex_mode:
            return "hex> "
        if not self.interactive:
            return "hcr> "
        return f"hcr {self.link.port or '-'} {self.link.state}> "

    # -- output from other threads -------------------------------------------

    def say(self, text: str) -> None:
        """A notice (link lost, reconnected): above the prompt, or on stderr.

        While a command owns the terminal (``watch`` drawing its panel, a
        ``ping`` printing its lines) a write to stderr would land in the middle
        of its screen, so an interactive session holds the notice until
        ``attach`` gives it a printer again at the next prompt.
        """
        with self._say_lock:
            printer = self.printer
            if printer is None and self.interactive:
                self._held.append(text)
                return
        if printer is not None:
            printer(text)
        else:
            click.echo(f"hcrctl: {text}", err=True)

    def attach(self, printer: Printer) -> None:
        """The prompt is back: print the notices and news held meanwhile, then print as they come."""
        with self._say_lock:
            held, self._held = self._held, []
            news, self._news = self._news, []
            self.printer = printer
        for text in held:
            printer(text)
        self._print_news(news, printer)

    def _print_news(self, news: list[Frame], printer: Printer) -> None:
        """News held together: one line with ``changes`` (a start among stations is one line, not one each)."""
        if self.monitor == "changes" and len(news) > 1:
            printer(news_line(news))
            return
        for frame in news:
            line = self.broadcasts.line_for(frame, True, self.monitor)
            if line is not None:
                printer(line)

    def _news_later(self) -> None:
        """What NEWS_WINDOW gathered: printed together, or held again if a command took the terminal."""
        with self._say_lock:
            self._news_due = None
            printer = self.printer
            if printer is None:
                return  # ``attach`` prints them with the next prompt
            news, self._news = self._news, []
        self._print_news(news, printer)

    def _hear_text(self, robot: Robot) -> None:
        """A ``Settings.robot_hooks`` entry: what the firmware prints reaches the monitor output too."""
        robot.add_traffic_hook(self._text)

    def _text(self, traffic: Traffic) -> None:
        """A line the firmware printed: every one with ``monitor on``, a changed one with ``changes``."""
        event, printer = traffic.event, self.printer
        if not isinstance(event, TextLine) or printer is None:
            return
        changed, self._last_text = event.text != self._last_text, event.text
        if self.monitor == "on" or (self.monitor == "changes" and changed):
            printer(f"text  {printable(event.text)}")

    def _unsolicited(self, frame: Frame) -> None:
        """From the reader thread: count it; print it if the monitor mode says so.

        A station first heard while a command owns the terminal (or before the
        first prompt) is announced at the next prompt, not lost.
        """
        news = self.broadcasts.offer(frame)
        with self._say_lock:
            printer = self.printer
            if printer is None:
                if news and self.interactive:
                    self._news.append(frame)
                return
            if news and self.monitor == "changes":  # gathered a moment: stations heard together are one line
                self._news.append(frame)
                if self._news_due is None:
                    self._news_due = threading.Timer(NEWS_WINDOW, self._news_later)
                    self._news_due.daemon = True
                    self._news_due.start()
                return
        line = self.broadcasts.line_for(frame, news, self.monitor)
        if line is not None:
            printer(line)

    # -- safety ----------------------------------------------------------------

    def send_stop(self) -> str:
        """The stop key: stop now, whatever is being typed. Returns what happened."""
        robot = self.link.robot
        if robot is None or not robot.connected:
            note = "stop NOT sent: not connected"
        else:
            try:
                robot.stop()
                note = f"stop sent to 0x{robot.address:02X} on {robot.port}"
            except HcrError as exc:
                note = f"stop NOT sent: {exc.one_line()}"
        self.stop_note = note
        return note

    def connect_at_start(self) -> HcrError | None:
        """Open the port named by --port (or the one USB port); the error, if any."""
        try:
            self.link.open()
        except HcrError as exc:
            return exc
        return None

    def close(self) -> None:
        """However the session ends: stop if anything moved, then release the port.

        Notices still held (the link dropped during the last command) go to
        stderr afterwards: the terminal is nobody's now.
        """
        self.printer = None
        self.link.close()
        with self._say_lock:
            held, self._held = self._held, []
        for text in held:
            click.echo(f"hcrctl: {text}", err=True)

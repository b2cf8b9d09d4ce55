"""What a daily user meets first: a typo's "did you mean", the global options' help, the hex-mode banner.

Each check runs the installed hcrctl (a typo on the command line, ``--help``, the
shell in a pty of its own width); the word choice behind "did you mean" is checked
in process as well, over the names the CLI really has.
"""

from __future__ import annotations

import pytest
from helpers import Terminal
from helpers_cli import clean_env, one_line, run, wire
from helpers_shell import shell_env

from hcrctl import __version__
from hcrctl.cli import SUBCOMMANDS
from hcrctl.cli.didyoumean import no_such_command
from hcrctl.cli.settings import global_options
from hcrctl.shell.hexmode import HELP, banner

#: The simulator without broadcasts: nothing but the banner lands between the command and the prompt.
QUIET_SIM = "sim://?broadcast_hz=0&map_hz=0"


def test_a_mistyped_command_is_exit_2_one_line_with_did_you_mean_and_nothing_sent(tmp_path):
    with wire() as tap:
        result = run(["--port", tap.path, "raed", "compass"], clean_env(tmp_path))
        assert result.returncode == 2
        assert result.stderr == (
            "hcrctl: error: No such command 'raed'. Did you mean 'read'? (see 'hcrctl --help')\n"
        )
        assert result.stdout == ""
        assert tap.read(quiet=0.1) == b""


@pytest.mark.parametrize(
    ("typed", "said"),
    [
        ("raed", "No such command 'raed'. Did you mean 'read'?"),  # not 'record' too: much farther off
        ("drvie", "No such command 'drvie'. Did you mean 'drive'?"),
        ("compleiton", "No such command 'compleiton'. Did you mean 'completion'?"),
        ("polt", "No such command 'polt'. (Did you mean one of: 'plot', 'ports'?)"),  # as close as each other
        ("xyzzy", "No such command 'xyzzy'."),
    ],
)
def test_did_you_mean_offers_only_the_closest_names(typed, said):
    assert no_such_command(typed, sorted(SUBCOMMANDS)) == said


def test_a_group_of_several_close_names_is_said_as_click_says_it(tmp_path):
    result = run(["polt"], clean_env(tmp_path))
    assert result.returncode == 2
    assert "(Did you mean one of: 'plot', 'ports'?)" in one_line(result.stderr)


def test_an_option_where_a_command_goes_is_still_clicks_own_error(tmp_path):
    """Only a word that could be a command gets a suggestion; ``--bogus`` is an unknown option."""
    result = run(["--bogus"], clean_env(tmp_path))
    assert result.returncode == 2
    assert "No such option '--bogus'" in one_line(result.stderr)


def test_every_global_option_says_what_it_is(tmp_path):
    assert all(option.help for option in global_options())
    text = " ".join(run(["--help"], clean_env(tmp_path)).stdout.split())
    assert (
        "--baud INTEGER Serial line rate, bit/s. Default: the --protocol's own (115200 for v0.15, 9600 for v0.11)."
        in text
    )


@pytest.mark.parametrize("spelling", ["-V", "--version"])
def test_the_version_is_asked_for_as_in_other_tools(tmp_path, spelling):
    result = run([spelling], clean_env(tmp_path))
    assert (result.returncode, result.stdout, result.stderr) == (0, f"hcrctl, version {__version__}\n", "")


@pytest.mark.parametrize("width", [20, 37, 60, 80, 100, 200])
def test_the_hex_banner_is_cut_between_words_only(width):
    lines = banner(width).splitlines()
    assert all(len(line) <= width for line in lines)
    assert " ".join(lines) == HELP  # no word cut in two, none lost
    assert len(lines) == 1 if width >= len(HELP) else len(lines) > 1


def test_the_hex_banner_fits_the_terminal_it_is_shown_in(tmp_path):
    """In a 60-column terminal (no COLUMNS: the width comes from the terminal itself), every banner
    line on the screen is whole words; left to the terminal, it wrapped mid-word."""
    env = {k: v for k, v in shell_env(tmp_path).items() if k not in ("COLUMNS", "LINES")}
    term = Terminal(["--port", QUIET_SIM, "shell"], size=(60, 30), env=env, alt_screen=True, strip=True)
    try:
        screen = term.run("hex").splitlines()
        first = next(i for i, line in enumerate(screen) if line.startswith("raw hex mode"))
        last = next(i for i in range(first, len(screen)) if screen[i].startswith("hex>"))
        shown = screen[first:last]
        assert len(shown) > 1
        assert " ".join(shown) == HELP
        term.send("\x04")  # Ctrl-D leaves hex mode
        term.wait_for(lambda _: term.cursor_line().startswith("hcr "))
        term.send("\x04")  # and the shell
        assert term.finish() == 0
    finally:
        term.close()


def test_the_shell_does_not_offer_the_commands_that_print_files_for_the_outer_shell(tmp_path):
    """``completion`` and ``man`` are for the login shell; inside hcrctl's shell they are unknown."""
    env = shell_env(tmp_path)
    term = Terminal(["--port", QUIET_SIM, "shell"], size=(100, 30), env=env, alt_screen=True, strip=True)
    try:
        screen = term.run("man")
        assert "No such command 'man'" in screen
    finally:
        term.close()

"""``hcrctl config``, ``config path``, ``config init [--force]``: the settings in effect, and the file.

Every setting is a global option (``settings.global_options``, the one
table): its value is what the command line, ``HCRCTL_<NAME>``, the config file
or the default made it, in that order, and Click records which one
(``get_parameter_source``), so nothing here restates the precedence. The
template ``config init`` writes is made from the same options, with their
help, range, default and variable as ``--help`` shows them. A command's table
in the file (``[bridge]``) is shown as the file sets it.
"""

from __future__ import annotations

import json
import os
import textwrap
from typing import Any, NamedTuple

import click

from ..config import config_path, file_settings
from ..errors import HcrError
from .output import emit, say
from .params import ByteNumber
from .settings import GlobalOption, Settings, config_defaults, config_keys, json_option

#: Where a value came from, by Click's name for it: what ``hcrctl config`` says.
SOURCES = {
    "COMMANDLINE": "command line",
    "ENVIRONMENT": "environment",
    "DEFAULT_MAP": "config file",
    "DEFAULT": "default",
}
#: The template's comment width.
WIDTH = 96


@click.group(invoke_without_command=True)
@json_option
@click.pass_context
def config(ctx: click.Context) -> None:
    """Show every setting with its value and its source: default, config file, environment, command line.

    \b
    hcrctl config               each setting, its value, where it came from (--json: one document)
    hcrctl config path          where the config file is read from
    hcrctl config init          write a commented template there (an existing file needs --force)
    """
    if ctx.invoked_subcommand is None:
        show(ctx.find_root(), ctx.obj)


@config.command()
@click.pass_obj
def path(settings: Settings) -> None:
    """Print where the config file is read from ($XDG_CONFIG_HOME/hcrctl/config.toml)."""
    where = config_path()
    emit(settings, {"path": where, "exists": os.path.lexists(where)}, where)


@config.command()
@click.option("--force", is_flag=True, help="Replace an existing config file (refused otherwise).")
@click.pass_context
def init(ctx: click.Context, force: bool) -> None:
    """Write a commented template of every setting to the config file."""
    where = config_path()
    write_new(where, template(ctx.find_root()), force)
    settings: Settings = ctx.obj
    if settings.as_json:
        emit(settings, {"path": where, "written": True}, where)
    else:
        say(f"config: wrote {where}: every setting, commented out; uncomment a line to set it")


# -- what is in effect -----------------------------------------------------------------------------


class Setting(NamedTuple):
    """One line of ``hcrctl config``: the key, what ``--json`` gives for it, and its value for people."""

    key: str
    record: dict[str, Any]
    shown: str


def show(root: click.Context, settings: Settings) -> None:
    """Every setting's value and source, and what the file's command tables set."""
    if isinstance(root.command, click.Group):
        config_defaults(root.command)  # a bad file is its error here, as for any other command
    where = config_path()
    found = settings_in_effect(root, where)
    exists = os.path.lexists(where)
    lines = [f"config file: {where}" + ("" if exists else " (none there)")]
    width = max(len(setting.key) for setting in found)
    lines += [f"{s.key:<{width}}  {s.shown:<24}  {source_text(s.record)}" for s in found]
    record = {"file": where, "exists": exists, "settings": {s.key: s.record for s in found}}
    emit(settings, record, "\n".join(lines))


def settings_in_effect(root: click.Context, where: str) -> list[Setting]:
    """Each global option's value and where it came from, then the values of the file's command tables."""
    in_file = {entry.key.replace("_", "-"): entry for entry in file_settings(where)}
    found = []
    for key, option in config_keys(root.command).items():
        name = option.name or key
        value = getattr(root.obj, name)
        source = root.get_parameter_source(name)
        record: dict[str, Any] = {
            "value": plain(value),
            "source": SOURCES[source.name] if source else "default",
        }
        if record["source"] == "command line":
            record["option"] = max(option.opts, key=len)
        elif record["source"] == "environment":
            record["variable"] = option.envvar
        elif record["source"] == "config file":
            record["line"] = in_file[key].line if key in in_file else None
        found.append(Setting(key, record, shown(value, option)))
    for key, entry in in_file.items():
        if "." in key:
            record = {"value": entry.value, "source": "config file", "line": entry.line}
            found.append(Setting(key, record, shown(entry.value)))
    return found


def source_text(row: dict[str, Any]) -> str:
    """``command line --port``, ``environment HCRCTL_TIMEOUT``, ``config file, line 3``, ``default``."""
    detail = row.get("option") or row.get("variable")
    if detail:
        return f"{row['source']} {detail}"
    return f"{row['source']}, line {row['line']}" if row.get("line") else row["source"]


def plain(value: Any) -> Any:
    """A setting as JSON holds it: an enum by its value, a tuple as a list."""
    if isinstance(value, tuple):
        return list(value)
    return getattr(value, "value", value)


def shown(value: Any, option: click.Option | None = None) -> str:
    """A setting for people: an address in hex, true/false, lists joined, nothing set said so."""
    value = plain(value)
    if value is None or value == []:
        return "(not set)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if option is not None and isinstance(option.type, ByteNumber) and isinstance(value, int):
        return f"0x{value:02X}"
    if isinstance(value, list):
        return ", ".join(map(str, value))
    return str(value)


# -- the template ----------------------------------------------------------------------------------

HEADER = """\
# hcrctl's config file: defaults for the global options, each by its long name.
# HCRCTL_<NAME> in the environment and the command line win over it; `hcrctl config` shows
# every setting in effect and where it came from. Uncomment a line to set it.
"""

FOOTER = """\
# A table named after a command holds that command's options, by long name, e.g.:
#     [bridge]
#     allow-origin = ["https://viewer.example:8080"]
"""


def template(root: click.Context) -> str:
    """The config file with every setting commented out: its help, then its range, default and variable
    as ``--help`` shows them, then a value to start from."""
    parts = [HEADER]
    for key, option in config_keys(root.command).items():
        record = option.get_help_record(root)
        about, _, extra = " ".join(record[1].split()).partition(" [") if record else ("", "", "")
        comment = textwrap.wrap(about, WIDTH - 2, break_on_hyphens=False) + ([f"[{extra}"] if extra else [])
        value = toml_value(example(option, root))
        parts.append("".join(f"# {line}\n" for line in comment) + f"# {key} = {value}\n")
    parts.append(FOOTER)
    return "\n".join(parts)


def example(option: click.Option, ctx: click.Context) -> Any:
    """The option's default, or, when it has none, the example its declaration gives."""
    default = option.get_default(ctx)
    if isinstance(default, (bool, int, float, str)) or not isinstance(option, GlobalOption):
        return default
    return option.example  # no default (None, or Click's own marker for none)


def toml_value(value: Any) -> str:
    """``value`` written in TOML (a TOML basic string is a JSON string for these)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(item) for item in value) + "]"
    return json.dumps(str(value), ensure_ascii=False)


def write_new(where: str, text: str, force: bool) -> None:
    """Write ``text`` at ``where``: only if nothing is there (created exclusively), or over it with ``force``."""
    from ..recording.outputs import check_outputs, written_whole

    label = "config file"
    check_outputs([(label, where)], force=force, regular_only=True)
    try:
        os.makedirs(os.path.dirname(where), exist_ok=True)
        with (
            written_whole(where, label, force=force) as temporary,
            open(temporary, "w", encoding="utf-8") as out,
        ):
            out.write(text)
    except OSError as exc:
        raise HcrError(f"cannot write {label} {where}: {exc.strerror or exc}") from None
